"""The fingerspelling handshapes of notebook 12: letters from joint angles of the corpus' hand model."""

from __future__ import annotations

import numpy as np
import pytest

from nlo_lab.corpus.fingerspelling import LETTERS, fingerspelling_demonstration, hand_landmarks, letter_angles
from nlo_lab.errors import SettingsError


def test_one_frame_per_letter_with_the_right_hand_up_and_palm_forward():
    demo = fingerspelling_demonstration("ALV")
    assert len(demo) == 3 and demo.meta["letters"] == ["A", "L", "V"]
    demo.validate()
    R = demo.wrist_rotations[:, 1]  # right hand
    assert (R[:, 2, 0] > 0.8).all()  # fingers (wrist x) up
    assert (-R[:, 0, 2] > 0.8).all()  # palm (-z of a right hand) forward


def test_letters_have_their_shape():
    lm = {c: hand_landmarks(c) for c in "ALVUS"}
    length = lambda p, tip: np.linalg.norm(p[tip] - p[0])  # noqa: E731
    # L: index extended, middle curled; the thumb stands out sideways (index side, +y)
    assert length(lm["L"], 8) > 1.6 * length(lm["L"], 12)
    assert lm["L"][4, 1] > 0.08
    # V: index and middle extended and further apart than in U; S: a fist, every tip near the palm
    assert np.linalg.norm(lm["V"][8] - lm["V"][12]) > np.linalg.norm(lm["U"][8] - lm["U"][12]) + 0.01
    assert max(length(lm["S"], t) for t in (8, 12, 16, 20)) < 0.9 * min(length(lm["V"], t) for t in (8, 12))


def test_unknown_letter_is_named():
    with pytest.raises(SettingsError, match="Q"):
        letter_angles("Q")
    with pytest.raises(SettingsError, match="no letters"):
        fingerspelling_demonstration("")
    assert set("ABCDEFILOSUVWXY5") == set(LETTERS)
