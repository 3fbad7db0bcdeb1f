"""The ``.pose`` reader's geometry for a live stream: one frame of landmarks in, one frame of a demonstration out.

:func:`nlo_lab.human.readers.pose.load_pose` reads a whole recording: several of its steps look at
the frames after the one they make (the Savitzky-Golay smoothing, the outlier tests that compare a
frame with both neighbours, the gap interpolation) or at the whole clip (the body's up direction,
the world scale, the metres per pixel, the hand's scale are medians or means over every frame). A
camera has no future frames, so :class:`CausalReader` does each step from the present and the
past only, with the reader's own conventions, constants and functions wherever they are causal
already (the body frame from the shoulders, the wrist frame from the hand, the hand pinned on the
arm's wrist and scaled to the forearm):

=========================  ======================================  ====================================================
step                       offline (``load_pose``)                 live (here)
=========================  ======================================  ====================================================
arms                       world landmarks [m]                     the same
world scale check          clip's median shoulder width            median of the last :data:`HISTORY_SECONDS`
metres per pixel           clip's medians                          medians of the last :data:`HISTORY_SECONDS`
spikes                     far from the midpoint of the neighbours a speed no arm reaches (:data:`SPIKE_SPEED`)
                           (Hampel): repaired                      since the last accepted sample: held
segment-length, palm and   repaired from both neighbours           not held back (see below)
wrist-rotation jumps
gaps of <= 0.25 s          interpolated                            the last value held
smoothing                  Savitzky-Golay (needs future frames)    One-Euro filter (:mod:`nlo_lab.live.one_euro`)
the body's up              clip's weighted mean: hips, else face,  the same, over the past (weights decaying with
                           else image                              :data:`UP_SECONDS`)
hand scale                 clip's median forearm / hand length     medians of the last :data:`HISTORY_SECONDS`
lengths the objective      clip's medians                          medians of the last :data:`HISTORY_SECONDS`
scales by                                                          (:meth:`CausalReader.body_lengths`)
=========================  ======================================  ====================================================

A held sample is a lag the learner sees, and a test that sees only the past cannot tell a flip of the
hand from a quick turn, nor a mis-detected forearm from one pointing at the camera. Measured on the
sample video (``benchmarks/live.py``'s stream, YuMi): with the offline tests made causal (a length or a
palm 1.4 times off the median of the last six samples, a wrist rotation 1 rad from the last one: held,
for at most 0.25 s) the optimised poses were 99 mm from the offline reader's human (wrists and elbows,
mapped to the robot), without them 47 mm (the offline retargeting: 45 mm); the rotation test alone held
back 14 samples of a hand that turned and cost 40 mm. Only a jump faster than any arm moves is held (a
sample held for longer than the longest gap is the new truth and is taken).
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from nlo_lab.human import ARM_JOINTS, SIDES, Demonstration
from nlo_lab.human.conditioning import orthonormalize
from nlo_lab.human.demonstration import FPS_RANGE
from nlo_lab.human.readers.pose import (
    HAND_FINGER_POINTS,
    HAND_PER_FOREARM,
    HIP_MIN_CONFIDENCE,
    MAX_GAP_SECONDS,
    MIN_CONFIDENCE,
    NOMINAL_SHOULDER_WIDTH,
)
from nlo_lab.human.transforms import body_frame_from_shoulders, wrist_frame_from_hand
from nlo_lab.live.holistic import FrameLandmarks
from nlo_lab.live.one_euro import OneEuroFilter

__all__ = ["HISTORY_SECONDS", "UP_SECONDS", "SPIKE_SPEED", "FilterSettings", "CausalReader", "POSE_INDEX"]

HISTORY_SECONDS = 5.0  # [s] the running medians (scales, segment lengths) look this far back
UP_SECONDS = 10.0  # [s] time constant of the up direction's decaying mean
WORLD_SHOULDER_RANGE = (0.15, 0.8)  # [m] plausible world shoulder widths (as the offline reader's)
# MediaPipe's pose landmark numbers (mediapipe.solutions.pose.PoseLandmark; tests check them)
POSE_INDEX = {"NOSE": 0, "LEFT_EYE": 2, "RIGHT_EYE": 5, "LEFT_EAR": 7, "RIGHT_EAR": 8, "LEFT_SHOULDER": 11, "RIGHT_SHOULDER": 12,
              "LEFT_ELBOW": 13, "RIGHT_ELBOW": 14, "LEFT_WRIST": 15, "RIGHT_WRIST": 16, "LEFT_HIP": 23, "RIGHT_HIP": 24}
SPIKE_SPEED = 8.0  # [m/s] a landmark that moved faster than this since its last accepted sample is a spike
_FACE_GROUPS = (("LEFT_EAR", "RIGHT_EAR"), ("LEFT_EYE", "RIGHT_EYE"), ("NOSE",))
_HAND_WRIST, _HAND_INDEX, _HAND_MIDDLE, _HAND_PINKY = 0, 5, 9, 17
_IMAGE_UP = np.array([0.0, -1.0, 0.0])


class FilterSettings:
    """The One-Euro filter's settings shared by every landmark track of a reader (points in metres).

    Defaults ``min_cutoff`` 2.5 Hz, ``beta`` 0.5 per metre, ``d_cutoff`` 1 Hz, chosen by measurement on the
    two shared Holistic recordings (25 fps) against the offline reader's conditioned points: they keep the
    elbows', wrists' and fingertips' frame-to-frame jitter (RMS second difference) at or below the offline
    reader's (arms 5 and 16 mm against 10 and 19; fingertips 31 and 29 against 26 and 34) while the arm points
    stay 16-18 mm from the offline ones on average; no filter at all stays 12-18 mm away with twice the
    offline jitter (arms 11 and 35 mm, fingertips 64 and 58), a cutoff of 0.5 Hz lags 23-28 mm behind.
    """

    def __init__(self, min_cutoff: float = 2.5, beta: float = 0.5, d_cutoff: float = 1.0):
        OneEuroFilter(min_cutoff, beta, d_cutoff)  # checks them
        self.min_cutoff, self.beta, self.d_cutoff = float(min_cutoff), float(beta), float(d_cutoff)

    def make(self) -> OneEuroFilter:
        return OneEuroFilter(self.min_cutoff, self.beta, self.d_cutoff)

    def as_dict(self) -> dict[str, float]:
        return {"min_cutoff": self.min_cutoff, "beta": self.beta, "d_cutoff": self.d_cutoff}


class _Recent:
    """Values of the last ``seconds``: their median (the causal stand-in for a clip's median)."""

    def __init__(self, seconds: float = HISTORY_SECONDS, most: int = 600):
        self.seconds = seconds
        self.items: deque[tuple[float, float]] = deque(maxlen=most)

    def add(self, t: float, value: float) -> None:
        if math.isfinite(value):
            self.items.append((t, float(value)))
        while self.items and self.items[0][0] < t - self.seconds:
            self.items.popleft()

    def median(self) -> float:
        return float(np.median([v for _, v in self.items])) if self.items else float("nan")

    def spread(self) -> tuple[float, float]:
        """``(median, 1.4826 MAD)``: a robust centre and standard deviation."""
        if not self.items:
            return float("nan"), float("nan")
        v = np.array([x for _, x in self.items])
        med = float(np.median(v))
        return med, 1.4826 * float(np.median(np.abs(v - med)))


class _DecayingMean:
    """The direction of a weighted sum of unit vectors whose weights decay with time constant :data:`UP_SECONDS`
    (the causal stand-in for the offline reader's confidence-weighted mean over the clip)."""

    def __init__(self) -> None:
        self.total, self.weight = np.zeros(3), 0.0
        self.time: float | None = None

    def add(self, vec: np.ndarray | None, weight: float, t: float) -> np.ndarray | None:
        """Add ``weight * unit(vec)`` at ``t``; the mean direction so far (None while there is none)."""
        if self.time is not None:
            decay = math.exp(-(t - self.time) / UP_SECONDS)
            self.total, self.weight = self.total * decay, self.weight * decay
        self.time = t
        n = float(np.linalg.norm(vec)) if vec is not None else 0.0
        if vec is not None and weight > 0 and math.isfinite(n) and n > 1e-9:
            self.total = self.total + weight * vec / n
            self.weight += weight
        norm = float(np.linalg.norm(self.total))
        return self.total / norm if self.weight > 0 and norm > 1e-9 else None


class _Track:
    """One group of points through time: gaps of at most ``max_gap`` seconds held, the rest filtered."""

    def __init__(self, settings: FilterSettings, max_gap: float):
        self.filter = settings.make()
        self.max_gap = max_gap
        self.value: np.ndarray | None = None
        self.seen = -math.inf  # time of the last accepted sample

    def reject(self, t: float) -> bool:
        """Whether a sample an outlier test rejects at ``t`` stays rejected: only while the held value is younger
        than ``max_gap`` (a rejection that would leave the track empty is accepted: then it is no outlier but a move)."""
        return self.value is not None and t - self.seen < self.max_gap

    def update(self, x: np.ndarray | None, t: float) -> np.ndarray | None:
        """``x (P, D)`` accepted at ``t`` (None: missing or rejected); the filtered value, the held one, or None."""
        if x is not None:
            self.value = self.filter(x, t)
            self.seen = t
            return self.value
        if self.value is not None and t - self.seen <= self.max_gap:
            return self.value
        self.value = None
        self.filter.reset()
        return None


class _SpikeTest:
    """A point that would have moved faster than :data:`SPIKE_SPEED` since its last accepted sample is a spike.

    The offline test (a point far from the midpoint of its two neighbours, beyond the clip's median + 4 MAD and
    5 cm) needs the next frame; its causal twin, the distance from the constant-velocity prediction of the last
    two samples, flagged 3 to 5 times the offline test's frames on the shared recordings: their wrists' residuals
    are heavy-tailed (p90 six times the median), real fast moves among them, and a live sample held back is a
    lag the learner sees. A speed no arm reaches is a test that does not depend on the frame rate: MediaPipe's
    wrists peaked at 3.5 and 5.1 m/s in the shared recordings, a mis-detection jumps much faster.
    """

    def __init__(self) -> None:
        self.last: tuple[float, np.ndarray] | None = None

    def is_spike(self, x: np.ndarray, t: float) -> bool:
        if self.last is None:
            return False
        t0, x0 = self.last
        return float(np.linalg.norm(x - x0)) > SPIKE_SPEED * (t - t0)

    def accept(self, x: np.ndarray, t: float) -> None:
        self.last = (t, np.array(x, dtype=np.float64))


class CausalReader:
    """One frame of MediaPipe landmarks after the other into one-frame demonstrations (see the module docstring).

    Args:
        filter: the One-Euro settings of every landmark (:class:`FilterSettings`); change them with :meth:`set_filter`.
        max_gap: [s] the longest a missing (or rejected) landmark is held (the offline reader's ``MAX_GAP_SECONDS``).

    Attributes:
        up_from: where the body's up came from in the last frame: ``"hips"``, ``"face"`` or ``"image"``.
        rejected: ``{"spike": n}``, the samples the spike test held back since the last :meth:`reset`.
        fps: the stream's frame rate estimated from the recent frames' times (the demonstration's ``fps``).
    """

    def __init__(self, filter: FilterSettings | None = None, max_gap: float = MAX_GAP_SECONDS):
        self.settings = filter or FilterSettings()
        self.max_gap = float(max_gap)
        self.reset()

    def reset(self) -> None:
        """Forget the past (a new person, a new stream)."""
        self._arms = {(s, j): _Track(self.settings, self.max_gap) for s in SIDES for j in ARM_JOINTS}
        self._spikes = {key: _SpikeTest() for key in self._arms}
        self._hands = {s: _Track(self.settings, self.max_gap) for s in SIDES}
        self._rotations = {s: _Track(self.settings, self.max_gap) for s in SIDES}
        self._hand_length = {s: _Recent() for s in SIDES}
        self._forearm = {s: _Recent() for s in SIDES}
        self._upper_arm = {s: _Recent() for s in SIDES}
        self._knuckles = {s: _Recent() for s in SIDES}
        self._world_width, self._image_width, self._world_xy = _Recent(), _Recent(), _Recent()
        self._hip_confidence = _Recent()
        self._up = {"hips": _DecayingMean(), "face": _DecayingMean()}
        self._times: deque[float] = deque(maxlen=30)
        self.up_from = "image"
        self.fps = 30.0
        self.rejected = {"spike": 0}  # samples held back so far

    def set_filter(self, **settings: float) -> None:
        """Change the One-Euro settings (``min_cutoff``, ``beta``, ``d_cutoff``) of every track; the next frame uses them."""
        new = FilterSettings(**{**self.settings.as_dict(), **settings})
        self.settings.min_cutoff, self.settings.beta, self.settings.d_cutoff = new.min_cutoff, new.beta, new.d_cutoff
        for track in [*self._arms.values(), *self._hands.values(), *self._rotations.values()]:
            track.filter.min_cutoff, track.filter.beta, track.filter.d_cutoff = new.min_cutoff, new.beta, new.d_cutoff

    # ---------------------------------------------------------------- one frame
    def read(self, lm: FrameLandmarks, t: float) -> Demonstration | None:
        """The one-frame demonstration (body frame, metres) of the landmarks seen at ``t`` [s], or None: no person."""
        self._times.append(t)
        if len(self._times) >= 2 and self._times[-1] > self._times[0]:
            self.fps = float(np.clip((len(self._times) - 1) / (self._times[-1] - self._times[0]), *FPS_RANGE))
        pose, world, vis = lm.pose, lm.world, lm.pose_visibility
        if pose is None or world is None or vis is None:
            return self._nobody(t)
        idx = POSE_INDEX
        seen = np.asarray(vis > MIN_CONFIDENCE)
        ls_i, rs_i = idx["LEFT_SHOULDER"], idx["RIGHT_SHOULDER"]
        if not (seen[ls_i] and seen[rs_i]):
            return self._nobody(t)

        # scales: the world width checked against the plausible range, metres per image pixel (running medians)
        self._world_width.add(t, float(np.linalg.norm(world[ls_i] - world[rs_i])))
        width = self._world_width.median()
        extra = 1.0 if WORLD_SHOULDER_RANGE[0] <= width <= WORLD_SHOULDER_RANGE[1] else NOMINAL_SHOULDER_WIDTH / width
        world = world * extra
        self._image_width.add(t, float(np.linalg.norm((pose[ls_i] - pose[rs_i])[:2])))
        self._world_xy.add(t, float(np.linalg.norm((world[ls_i] - world[rs_i])[:2])))
        m_per_px = self._world_xy.median() / self._image_width.median()

        # arm points: outliers rejected (held), then filtered, in the camera-aligned metric frame
        points = {}
        for side in SIDES:
            raw = {j: world[idx[f"{side.upper()}_{j.upper()}"]] for j in ARM_JOINTS}
            ok = {j: bool(seen[idx[f"{side.upper()}_{j.upper()}"]]) for j in ARM_JOINTS}
            for j in ARM_JOINTS:
                key = (side, j)
                spike = ok[j] and self._spikes[key].is_spike(raw[j], t)
                take = ok[j] and not (spike and self._arms[key].reject(t))
                if ok[j] and not take:
                    self.rejected["spike"] += 1
                if take:
                    self._spikes[key].accept(raw[j], t)
                value = self._arms[key].update(raw[j][None] if take else None, t)
                points[key] = None if value is None else value[0]
        ls, rs = points["left", "shoulder"], points["right", "shoulder"]
        if ls is None or rs is None:
            return self._nobody(t)

        # the body frame: origin between the shoulders, up from the hips, else the face, else the image
        up = self._up_direction(vis, world, seen, ls, rs, t)
        origin, R_src_body = body_frame_from_shoulders(ls[None], rs[None], up)
        if not np.isfinite(R_src_body).all():
            return self._nobody(t)
        R_body_src = R_src_body[0].T
        arms = np.full((1, 2, 3, 3), np.nan)
        arm_mask = np.zeros((1, 2, 3), bool)
        for k, side in enumerate(SIDES):
            for i, joint in enumerate(ARM_JOINTS):
                p = points[side, joint]
                if p is not None:
                    arms[0, k, i] = R_body_src @ (p - origin[0])
                    arm_mask[0, k, i] = True
        rots = np.full((1, 2, 3, 3), np.nan)
        wrist_mask = np.zeros((1, 2), bool)
        fingers = np.full((1, 2, 5, 2, 3), np.nan)
        finger_mask = np.zeros((1, 2, 5), bool)
        for s, side in enumerate(SIDES):
            if arm_mask[0, s, 0] and arm_mask[0, s, 1]:
                self._upper_arm[side].add(t, float(np.linalg.norm(arms[0, s, 1] - arms[0, s, 0])))
            if arm_mask[0, s, 1] and arm_mask[0, s, 2]:
                self._forearm[side].add(t, float(np.linalg.norm(arms[0, s, 2] - arms[0, s, 1])))
            hand, R = self._hand(side, lm, R_body_src, m_per_px, t)
            if hand is None or not arm_mask[0, s, 2]:
                continue
            hand = arms[0, s, 2] + hand  # pinned on the arm's wrist
            for f, (b, tip) in enumerate(HAND_FINGER_POINTS):
                fingers[0, s, f] = hand[b], hand[tip]
                finger_mask[0, s, f] = True
            knuckles = fingers[0, s, 1:, 0] - arms[0, s, 2]  # index..pinky bases from the wrist (the targets' hand length)
            self._knuckles[side].add(t, float(np.linalg.norm(knuckles, axis=-1).mean()))
            if R is not None:
                rots[0, s], wrist_mask[0, s] = R, True
        meta = {"format": "live", "up_from": self.up_from, "depth": "world", "metres_per_pixel": float(m_per_px), "time": float(t)}
        return Demonstration.from_arrays(self.fps, arms, arm_mask, rots, wrist_mask, fingers, finger_mask, name="live", meta=meta)

    def body_lengths(self) -> dict[str, np.ndarray]:
        """The demonstrator's lengths as the objective's targets take them from a whole recording (medians over its
        frames), here over the last :data:`HISTORY_SECONDS`: ``{"arm_length": upper + forearm, "fore_length",
        "hand_length": wrist -> knuckles}``, each ``(2,)`` [m] for (left, right); NaN where not seen yet."""
        upper = np.array([self._upper_arm[s].median() for s in SIDES])
        fore = np.array([self._forearm[s].median() for s in SIDES])
        return {"arm_length": upper + fore, "fore_length": fore, "hand_length": np.array([self._knuckles[s].median() for s in SIDES])}

    def _nobody(self, t: float) -> Demonstration | None:
        """Nobody (or no shoulders) at ``t``: every track's gap grows (the held values expire after ``max_gap``); None."""
        for track in (*self._arms.values(), *self._hands.values(), *self._rotations.values()):
            track.update(None, t)
        return None

    def _up_direction(self, vis: np.ndarray, world: np.ndarray, seen: np.ndarray, ls: np.ndarray, rs: np.ndarray,
                      t: float) -> np.ndarray:
        idx = POSE_INDEX
        centre = (ls + rs) / 2
        hip_conf = float(min(vis[idx["LEFT_HIP"]], vis[idx["RIGHT_HIP"]]))
        self._hip_confidence.add(t, hip_conf)
        hips = self._up["hips"].add(centre - (world[idx["LEFT_HIP"]] + world[idx["RIGHT_HIP"]]) / 2, hip_conf, t)
        face_vec, face_w = None, 0.0
        for group in _FACE_GROUPS:
            ids = [idx[n] for n in group]
            if seen[ids].all():
                face_vec = world[ids].mean(axis=0) - centre
                face_vec[2] = 0.0  # in the image plane, as offline: MediaPipe's depth of the face is unreliable
                face_w = float(vis[ids].min())
                break
        face = self._up["face"].add(face_vec, face_w, t)
        if hips is not None and self._hip_confidence.median() >= HIP_MIN_CONFIDENCE:
            self.up_from = "hips"
            return hips
        if face is not None:
            self.up_from = "face"
            return face
        self.up_from = "image"
        return _IMAGE_UP

    def _hand(self, side: str, lm: FrameLandmarks, R_body_src: np.ndarray, m_per_px: float,
              t: float) -> tuple[np.ndarray | None, np.ndarray | None]:
        """``(21, 3)`` the hand's points relative to its wrist in the body frame [m], scaled to the forearm, and its
        wrist rotation (each None where not seen or held too long)."""
        pts = (lm.hands or {}).get(side)
        rel = None
        if pts is not None and np.isfinite(pts).all():
            z_scale = lm.width if np.abs(pts[:, 2]).max() <= 10.0 else 1.0  # MediaPipe's normalised z, as offline
            rel = ((pts - pts[:1]) * np.array([m_per_px, m_per_px, m_per_px * z_scale])) @ R_body_src.T
        rel = self._hands[side].update(rel, t)
        if rel is None:
            self._rotations[side].update(None, t)
            return None, None
        along = np.linalg.norm(np.diff(rel[[0, 9, 10, 11, 12]], axis=0), axis=-1).sum()  # wrist -> middle tip along the finger
        self._hand_length[side].add(t, float(along))
        fore, length = self._forearm[side].median(), self._hand_length[side].median()
        scale = HAND_PER_FOREARM * fore / length if math.isfinite(fore) and fore > 0 and length > 0 else 1.0
        hand = rel * scale
        R = wrist_frame_from_hand(hand[_HAND_WRIST], hand[_HAND_INDEX], hand[_HAND_PINKY], hand[_HAND_MIDDLE])
        smoothed = self._rotations[side].update(R.reshape(1, 9) if np.isfinite(R).all() else None, t)
        return hand, (None if smoothed is None else orthonormalize(smoothed.reshape(3, 3)))
