"""The hand-only URDFs of benchmarks/hands/ (dex-retargeting's robot in benchmarks/hands.py): generated,
and the same hand as YuMi's: forward kinematics relative to the wrist link equals yumi.urdf's."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest
import yourdfpy

ROOT = Path(__file__).resolve().parents[2]
HANDS = ROOT / "benchmarks" / "hands"
YUMI = ROOT / "assets" / "robots" / "yumi.urdf"
DEX_PYTHON = ROOT / ".venv-bench" / "bin" / "python"


def _generator():
    spec = importlib.util.spec_from_file_location("make_hand_urdf", HANDS / "make_hand_urdf.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("s, side", [("l", "left"), ("r", "right")])
def test_hand_urdfs_are_the_generators_output(s, side):
    assert _generator().build(s) == (HANDS / f"yumi_hand_{side}.urdf").read_text(), "regenerate with benchmarks/hands/make_hand_urdf.py"


@pytest.mark.parametrize("s, side", [("l", "left"), ("r", "right")])
def test_hand_urdf_kinematics_equal_yumis_relative_to_the_wrist_link(s, side):
    hand = yourdfpy.URDF.load(str(HANDS / f"yumi_hand_{side}.urdf"), build_collision_scene_graph=False, load_meshes=False)
    yumi = yourdfpy.URDF.load(str(YUMI), build_collision_scene_graph=False, load_meshes=False)
    actuated = list(hand.actuated_joint_names)
    assert len(actuated) == 6 and all(j in yumi.actuated_joint_names for j in actuated)
    rng = np.random.default_rng(0)
    wrist = f"yumi_link_7_{s}"
    tips = [f"yumi_hand_{s}_{f}_tip" for f in ("thumb", "index", "middle", "ring", "pinky")]
    for _ in range(5):
        cfg = {}
        for name in actuated:
            lim = hand.joint_map[name].limit
            cfg[name] = rng.uniform(lim.lower, lim.upper)
        hand.update_cfg(cfg)
        full = {n: 0.3 for n in yumi.actuated_joint_names} | cfg
        yumi.update_cfg(full)
        for tip in tips:
            expected = np.linalg.inv(yumi.get_transform(wrist)) @ yumi.get_transform(tip)
            np.testing.assert_allclose(hand.get_transform(tip, wrist), expected, atol=1e-9)


@pytest.mark.skipif(not DEX_PYTHON.is_file(), reason="no .venv-bench (make bench-venv builds dex-retargeting's environment)")
def test_dex_runner_retargets_an_open_and_a_closed_hand(tmp_path):
    """dex-retargeting with our configs: an open human hand gives an open robot hand, a fist a closed one."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        import hands
    finally:
        sys.path.pop(0)
    hand = yourdfpy.URDF.load(str(HANDS / "yumi_hand_right.urdf"), build_collision_scene_graph=False, load_meshes=False)
    points = []
    for closed in (0.0, 1.0):
        cfg = {n: closed * hand.joint_map[n].limit.upper for n in hand.actuated_joint_names}
        hand.update_cfg(cfg)
        p = np.full((21, 3), np.nan)
        p[0] = 0.0
        for i, f in zip(hands.TIPS, ("thumb", "index", "middle", "ring", "pinky"), strict=True):
            p[i] = hand.get_transform(f"yumi_hand_r_{f}_tip", "yumi_link_7_r")[:3, 3]
        points.append(p)
    data = {"points": np.array(points), "side": np.array([1, 1]), "segment": np.array([0, 1]), "scaling": np.ones(2)}
    out = hands.run_dex(DEX_PYTHON, data)
    q = out["q_unfiltered"]
    assert q.shape == (2, 6) and np.isfinite(q).all()
    fingers = slice(2, 6)  # index..pinky proximal
    assert (q[0, fingers] < 0.15).all(), q[0]
    assert (q[1, fingers] > 1.2).all(), q[1]
    # timed passes: the same angles, the per-call seconds of the median pass (by its total)
    three = hands.run_dex(DEX_PYTHON, data, passes=3)
    for variant in ("filtered", "unfiltered"):
        np.testing.assert_array_equal(three[f"q_{variant}"], out[f"q_{variant}"])
        totals = three[f"pass_seconds_{variant}"]
        assert totals.shape == (3,) and three[f"seconds_{variant}"].shape == (2,)
        assert three[f"seconds_{variant}"].sum() == pytest.approx(float(np.median(totals)), rel=1e-12)
