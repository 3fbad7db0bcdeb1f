"""From a ``.pose`` file's landmarks to the arms in metres: conditioning, depth of image-only arms, the body's up.

The steps of :func:`nlo_lab.human.io_pose.load_pose` that turn landmarks into geometry (the
reader's module docstring says why each is done so): :func:`condition_arms` (outliers, gaps,
smoothing), :func:`reconstruct_depth` (elbow and wrist depth from the segment lengths when
the file has no world landmarks), :func:`face_centre` and :func:`up_direction` (the clip's up,
from the hips, else the face, else the image).
"""

from __future__ import annotations

import numpy as np

from nlo_lab.human import conditioning as cond
from nlo_lab.human import proportions
from nlo_lab.human.demonstration import SIDES
from nlo_lab.human.pose_file import PoseComponents
from nlo_lab.human.transforms import fill_gaps

__all__ = [
    "NOMINAL_SHOULDER_WIDTH",
    "HIP_MIN_CONFIDENCE",
    "DEPTH_SIGN_MARGIN",
    "median_shoulder_distance",
    "condition_arms",
    "reconstruct_depth",
    "face_centre",
    "up_direction",
]

NOMINAL_SHOULDER_WIDTH = proportions.SHOULDER_WIDTH  # [m] shoulder-joint to shoulder-joint of an adult (scale of image-only files)
HIP_MIN_CONFIDENCE = 0.5  # hips below this median confidence are MediaPipe's guess: up comes from the face
DEPTH_SIGN_MARGIN = 0.05  # [m] MediaPipe's z must put a point this much further away to count as "away"
_SEGMENT_PER_SHOULDER = {"upper": proportions.UPPER_ARM / proportions.SHOULDER_WIDTH, "fore": proportions.FOREARM / proportions.SHOULDER_WIDTH}
_IMAGE_UP = np.array([0.0, -1.0, 0.0])  # image y points down
_FACE_POINTS = (("LEFT_EAR", "RIGHT_EAR"), ("LEFT_EYE", "RIGHT_EYE"), ("NOSE",))


def median_shoulder_distance(ls: np.ndarray, rs: np.ndarray, ok: np.ndarray, dims: slice) -> float:
    d = np.linalg.norm((ls - rs)[ok][:, dims], axis=-1)
    return float(np.median(d)) if d.size else float("nan")


def condition_arms(pts: dict, fps: float, max_gap: int, condition: bool = True) -> tuple[dict, dict]:
    """Outlier frames of every arm point removed, gaps interpolated, points smoothed.

    Returns the conditioned ``{(side, joint): (values (T, 3), valid (T,))}`` and counts of
    repaired frames per kind (``meta["conditioning"]``).
    """
    if not condition:
        return {k: fill_gaps(v, ok, max_gap) for k, (v, ok) in pts.items()}, {}
    bad = {k: cond.spike_frames(v, ok) for k, (v, ok) in pts.items()}
    counts = {"spike_frames": int(sum(b.sum() for b in bad.values())), "segment_jump_frames": 0}
    for side in SIDES:
        for parent, child in (("shoulder", "elbow"), ("elbow", "wrist")):
            (pv, pok), (cv, cok) = pts[side, parent], pts[side, child]
            jump = cond.segment_jump_frames(pv, cv, pok & cok & ~bad[side, parent]) & ~bad[side, child]
            counts["segment_jump_frames"] += int(jump.sum())
            bad[side, child] = bad[side, child] | jump
    window = cond.window_frames(fps)
    out = {}
    for k, (v, ok) in pts.items():
        values, valid = fill_gaps(v, ok & ~bad[k], max_gap)
        out[k] = cond.savgol(values, valid, window), valid
    counts["smoothing_window_frames"] = window
    return out, counts


def reconstruct_depth(filled: dict, image: dict, z_to_m: float) -> tuple[dict, dict]:
    """Image-only arms: depth of elbows and wrists from the segment lengths (module docstring).

    ``filled`` holds image-plane points in metres with z = 0; ``image`` the raw landmarks,
    whose z (times ``z_to_m``) only chooses the sign.
    """
    out = dict(filled)
    lengths = {}
    (ls, lok), (rs, rok) = filled["left", "shoulder"], filled["right", "shoulder"]
    width = np.linalg.norm((ls - rs)[lok & rok], axis=-1)
    width = float(np.median(width)) if width.size else NOMINAL_SHOULDER_WIDTH
    for side in SIDES:
        z_parent = np.zeros(len(ls))
        for parent, child, seg in (("shoulder", "elbow", "upper"), ("elbow", "wrist", "fore")):
            (pv, pok), (cv, cok) = out[side, parent], filled[side, child]
            both = pok & cok
            planar = np.linalg.norm((cv - pv)[:, :2], axis=-1)[both]
            L = max(float(np.percentile(planar, 90)) if planar.size else 0.0, _SEGMENT_PER_SHOULDER[seg] * width)
            lengths[f"{side}_{seg}"] = round(L, 4)
            dz_img = (image[side, child][0][:, 2] - image[side, parent][0][:, 2]) * z_to_m
            toward = np.where(np.nan_to_num(dz_img) > DEPTH_SIGN_MARGIN, 1.0, -1.0)
            z = z_parent + cond.depth_from_lengths(pv, cv, L, toward)
            values = cv.copy()
            values[:, 2] = z
            out[side, child] = (np.where(cok[:, None], values, np.nan), cok)
            z_parent = z
    return out, lengths


def face_centre(comps: PoseComponents, source: str, use_world: bool, unscale: np.ndarray, extra: float,
                 m_per_px: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The face's reference point ``(T, 3)`` in the arms' frame and its weight ``(T,)``, or None.

    Ears' midpoint, else eyes', else the nose (from the arms' component); else the mean
    of the face mesh (image landmarks, direction only: the world and image axes agree).
    """
    names = comps.names.get(source, [])
    for group in _FACE_POINTS:
        if all(n in names for n in group):
            got = [comps.point(source, n) for n in group]
            seen = np.logical_and.reduce([ok for _, ok, _ in got])
            if seen.sum() >= 1:
                weight = np.minimum.reduce([c for _, _, c in got]) * seen
                centre = np.mean([v for v, _, _ in got], axis=0)
                scale = unscale * extra if use_world else unscale
                return centre * scale, weight
    for comp in ("FACE_LANDMARKS", "FACE"):
        if comp in comps.names:
            v, seen = comps.values[comp], comps.observed[comp]
            frames = seen.mean(axis=1) > 0.5
            if frames.any():
                centre = np.where(seen[..., None], v, 0.0).sum(1) / np.maximum(seen.sum(1), 1)[:, None]
                centre = centre * np.array([m_per_px, m_per_px, 0.0])  # in the image plane only
                return centre, frames.astype(float)
    return None


def _mean_direction(vec: np.ndarray, weight: np.ndarray) -> np.ndarray | None:
    n = np.linalg.norm(vec, axis=-1)
    w = np.where(np.isfinite(n) & (n > 1e-9), np.nan_to_num(weight), 0.0)
    if w.sum() <= 0:
        return None
    mean = (np.nan_to_num(vec) / np.where(w > 0, n, 1.0)[:, None] * w[:, None]).sum(0)
    norm = np.linalg.norm(mean)
    return mean / norm if norm > 1e-9 else None


def up_direction(ls, rs, shoulders_ok, hips, face) -> tuple[np.ndarray, str]:
    """The clip's up direction in the arms' frame and where it came from (module docstring)."""
    centre = (ls + rs) / 2
    if len(hips) == 2:
        (lh, lw), (rh, rw) = hips
        w = np.minimum(lw, rw) * shoulders_ok
        if np.median(np.minimum(lw, rw)) >= HIP_MIN_CONFIDENCE:
            up = _mean_direction(centre - (lh + rh) / 2, w)
            if up is not None:
                return up, "hips"
    if face is not None:
        point, w = face
        vec = point - centre
        vec[:, 2] = 0.0  # in the image plane: invariant to camera roll, and MediaPipe's depth of the face is noisy
        up = _mean_direction(vec, w * shoulders_ok)
        if up is not None:
            return up, "face"
    return _IMAGE_UP, "image"
