"""Conditioning of noisy landmark trajectories (monocular pose estimation) before retargeting.

MediaPipe Holistic on a video gives each frame on its own: points jitter by a
centimetre or more, a forearm can halve in length for one frame, a wrist can jump
0.6 m in depth and back, a hand orientation can flip. The reader
(:mod:`nlo_lab.human.readers.pose`) runs these steps, each a small function here:

1. :func:`spike_frames`: a point far from the median of its neighbours (a Hampel
   filter on the 3-D position) is an outlier of that frame.
2. :func:`segment_jump_frames`: a segment (upper arm, forearm, palm) whose length
   differs from the median of its neighbours by more than :data:`JUMP_RATIO` marks its
   distal point as an outlier of that frame.
3. Outliers become missing points; gaps of at most ``MAX_GAP_SECONDS`` are then
   interpolated (``transforms.fill_gaps``): repaired, not dropped.
4. :func:`savgol`: Savitzky-Golay smoothing (a local least-squares polynomial, zero
   lag, keeps the peaks of a fast sign better than a moving average), on each run of
   valid frames separately.
5. :func:`depth_from_lengths`: for image-only recordings, the depth of elbow and
   wrist from the projected and the true segment lengths.
6. :func:`orthonormalize`: rotations filtered entry-wise are projected back onto
   rotations (nearest in the Frobenius norm).

Parameters, chosen by measurement (``python benchmarks/conditioning.py``, 10 clips of the
synthetic test split at 15 and 25 fps with the real recordings' noise added, σ = 0.8 mm
per coordinate estimated from their second differences, plus outlier frames on 2 % of the
point-frames moved 0.2-0.5 m): RMS error of elbows and wrists against the truth, raw
50.4 mm; smoothing alone (no repair) 35 mm (window 0.12 s) to 26 mm (0.44 s): a moving
outlier is smeared, not removed; repair + smoothing 2.4 mm with a 0.12-0.20 s window,
3.1 mm at 0.28 s, 3.5 mm at 0.36 s, 5.6 mm at 0.44 s (longer windows flatten fast signs),
order 2 and 3 equal. Hence :data:`SMOOTH_SECONDS` = 0.2 (5 frames at 15-25 fps) and
:data:`SMOOTH_ORDER` = 2. The spike test's half-window :data:`SPIKE_HALF_WINDOW` = 3
catches outliers of up to two frames.
"""

from __future__ import annotations

import numpy as np

from nlo_lab.human.demonstration import Demonstration
from nlo_lab.human.transforms import fill_gaps

__all__ = [
    "SMOOTH_SECONDS",
    "SMOOTH_ORDER",
    "SPIKE_HALF_WINDOW",
    "SPIKE_SIGMAS",
    "SPIKE_FLOOR",
    "JUMP_RATIO",
    "savgol",
    "window_frames",
    "spike_frames",
    "segment_jump_frames",
    "depth_from_lengths",
    "orthonormalize",
    "rotation_steps",
    "continuous_rotations",
    "condition_demonstration",
    "ROTATION_JUMP",
]

SMOOTH_SECONDS = 0.2  # Savitzky-Golay window [s] (5 frames at 15-25 fps)
SMOOTH_ORDER = 2  # its polynomial order
SPIKE_HALF_WINDOW = 3  # neighbours on each side the Hampel filter compares a frame with
SPIKE_SIGMAS = 4.0  # outlier beyond this many robust standard deviations (1.4826 MAD) ...
SPIKE_FLOOR = 0.05  # [m] ... and at least this far from the neighbours' median
JUMP_RATIO = 1.4  # a segment longer or shorter than its neighbours' median by this factor jumped


def window_frames(fps: float, seconds: float | None = None, order: int | None = None) -> int:
    """An odd window length [frames] of about ``seconds`` (default :data:`SMOOTH_SECONDS`), at least ``order + 2``."""
    seconds = SMOOTH_SECONDS if seconds is None else seconds
    order = SMOOTH_ORDER if order is None else order
    w = int(round(seconds * fps))
    w = max(w, order + 2)
    return w if w % 2 else w + 1


def _runs(valid: np.ndarray):
    """``(start, stop)`` of each run of True."""
    v = np.concatenate([[False], np.asarray(valid, bool), [False]])
    edges = np.flatnonzero(np.diff(v.astype(np.int8)))
    return zip(edges[::2], edges[1::2], strict=True)


def _savgol_run(x: np.ndarray, window: int, order: int) -> np.ndarray:
    """Smooth one run ``(n, D)``: least-squares polynomial of ``order`` over ``window``
    samples, evaluated at the centre; the first and last ``window // 2`` samples are
    evaluated on the polynomial fitted to the first / last window (no padding)."""
    n = x.shape[0]
    w = min(window, n if n % 2 else n - 1)
    if w < order + 2:
        return x.copy()
    h = w // 2
    t = np.arange(-h, h + 1, dtype=np.float64)
    A = np.vander(t, order + 1, increasing=True)  # (w, order + 1)
    P = np.linalg.pinv(A)  # (order + 1, w): polynomial coefficients from samples
    out = np.empty_like(x)
    win = np.lib.stride_tricks.sliding_window_view(x, w, axis=0)  # (n - w + 1, D, w)
    out[h : n - h] = win @ P[0]  # the fitted value at t = 0
    edge = A[:h] @ P  # (h, w): values at t = -h .. -1 from the first window
    out[:h] = edge @ x[:w]
    out[n - h :] = (A[h + 1 :] @ P) @ x[n - w :]
    return out


def savgol(values: np.ndarray, valid: np.ndarray, window: int, order: int | None = None) -> np.ndarray:
    """Savitzky-Golay smoothing along axis 0 of ``values (T, ...)``, on each run of ``valid`` frames.

    Invalid frames are returned unchanged; a run shorter than ``order + 2`` frames too.
    ``order`` defaults to :data:`SMOOTH_ORDER`.
    """
    order = SMOOTH_ORDER if order is None else order
    x = np.array(values, dtype=np.float64, copy=True)
    flat = x.reshape(x.shape[0], -1)
    for a, b in _runs(valid):
        flat[a:b] = _savgol_run(flat[a:b], window, order)
    return x


def _local_median(x: np.ndarray, valid: np.ndarray, half: int) -> np.ndarray:
    """Per frame, the median over the valid frames in ``[t - half, t + half]`` without t itself; NaN if none."""
    T = x.shape[0]
    out = np.full(x.shape, np.nan)
    xs = np.where(valid.reshape((T,) + (1,) * (x.ndim - 1)), x, np.nan)
    for t in range(T):
        idx = [i for i in range(max(0, t - half), min(T, t + half + 1)) if i != t]
        block = xs[idx]
        if np.isfinite(block).any():
            out[t] = np.nanmedian(block, axis=0)
    return out


def _neighbour_distance(points: np.ndarray, valid: np.ndarray, half: int) -> np.ndarray:
    """Per frame, how far the point is from the midpoint of its neighbours ``k`` frames before and
    after, the smallest over ``k = 1 .. half`` where both are valid; NaN where none is.

    A smooth motion, however fast, passes close to the midpoint of its neighbours at
    ``k = 1`` (the error is its acceleration times ``dt²``); a spike of one or two frames
    is far from every such midpoint. Distances, not coordinates: rotation-invariant.
    """
    T = points.shape[0]
    out = np.full(T, np.inf)
    for k in range(1, half + 1):
        if T <= 2 * k:
            break
        mid = (points[: T - 2 * k] + points[2 * k :]) / 2.0  # midpoint of frames t - k and t + k, for t = k .. T-k-1
        both = valid[: T - 2 * k] & valid[2 * k :] & valid[k : T - k]
        d = np.where(both, np.linalg.norm(points[k : T - k] - mid, axis=-1), np.inf)
        out[k : T - k] = np.minimum(out[k : T - k], d)
    out[~np.isfinite(out)] = np.nan
    return out


def spike_frames(points: np.ndarray, valid: np.ndarray, half: int = SPIKE_HALF_WINDOW,
                 sigmas: float = SPIKE_SIGMAS, floor: float = SPIKE_FLOOR) -> np.ndarray:
    """``(T,)`` frames where the point ``(T, 3)`` is an outlier (a Hampel filter on the position).

    A frame is an outlier when its distance to its neighbours' midpoint exceeds both
    ``floor`` [m] and the clip's median of that distance plus ``sigmas`` robust standard
    deviations (1.4826 MAD). Distances, not coordinates: the test does not depend on the
    camera's orientation.
    """
    valid = np.asarray(valid, bool)
    d = _neighbour_distance(points, valid, half)
    ok = valid & np.isfinite(d)
    if ok.sum() < 3:
        return np.zeros(len(points), bool)
    mad = 1.4826 * np.median(np.abs(d[ok] - np.median(d[ok])))
    threshold = max(floor, np.median(d[ok]) + sigmas * mad)
    return ok & (d > threshold)


def segment_jump_frames(parent: np.ndarray, child: np.ndarray, valid: np.ndarray,
                        ratio: float = JUMP_RATIO, half: int = SPIKE_HALF_WINDOW) -> np.ndarray:
    """``(T,)`` frames where the segment parent -> child is ``ratio`` times longer or shorter
    than the median of its neighbours (a mis-detected child point)."""
    valid = np.asarray(valid, bool)
    length = np.linalg.norm(child - parent, axis=-1)
    med = _local_median(length, valid, half)
    ok = valid & np.isfinite(med) & (med > 0)
    r = np.where(ok, length / np.where(ok, med, 1.0), 1.0)
    return ok & ((r > ratio) | (r < 1.0 / ratio))


def depth_from_lengths(parent: np.ndarray, child: np.ndarray, length: float, toward: np.ndarray) -> np.ndarray:
    """Depth offset of ``child`` from ``parent`` so that the segment has its true ``length``.

    With the image-plane offset ``(dx, dy)`` of the segment, ``|dz| = sqrt(L² - dx² - dy²)``
    (0 where the projection is already as long as ``L``). The sign is ambiguous in one
    image; ``toward (T,)`` gives it: -1 towards the camera (image z decreases), +1 away.

    Args:
        parent, child: ``(T, 3)`` points whose first two coordinates are the image plane [m].
        length: the segment's true length [m].
        toward: ``(T,)`` sign of the depth offset.

    Returns:
        ``(T,)`` depth offsets [m].
    """
    planar = np.linalg.norm((child - parent)[:, :2], axis=-1)
    return np.asarray(toward, float) * np.sqrt(np.clip(length * length - planar * planar, 0.0, None))


def orthonormalize(R: np.ndarray) -> np.ndarray:
    """The rotation nearest to each ``(..., 3, 3)`` matrix (SVD; NaN stays NaN)."""
    out = np.full(R.shape, np.nan)
    ok = np.isfinite(R).all(axis=(-1, -2))
    if ok.any():
        U, _, Vt = np.linalg.svd(R[ok])
        d = np.sign(np.linalg.det(U @ Vt))
        U[..., :, -1] *= d[..., None]
        out[ok] = U @ Vt
    return out


def rotation_steps(R: np.ndarray) -> np.ndarray:
    """``(T-1,)`` angle [rad] between consecutive rotations ``(T, 3, 3)`` (NaN where either is NaN)."""
    rel = np.einsum("tji,tjk->tik", R[:-1], R[1:])
    c = (np.trace(rel, axis1=-2, axis2=-1) - 1.0) / 2.0
    return np.arccos(np.clip(c, -1.0, 1.0))


def condition_demonstration(demo, max_gap_seconds: float = 0.25):
    """A copy of ``demo`` (any source, body frame) with the conditioning of the module docstring.

    Arm points: spikes and segment-length jumps removed, gaps of at most
    ``max_gap_seconds`` interpolated, Savitzky-Golay smoothing. Finger points: smoothed.
    Wrist rotations: isolated flips (more than 1 rad from both neighbours) repaired,
    smoothed entry-wise, projected back onto rotations. The ``.pose`` reader does the same
    in the camera frame (plus hand scaling and depth); this is for other sources, e.g. a
    demonstration with injected noise.
    """
    fps = float(demo.fps)
    max_gap = int(round(max_gap_seconds * fps))
    window = window_frames(fps)
    arms, arm_mask = demo.arm_positions.copy(), demo.arm_mask.copy()
    for s in range(2):
        bad = [spike_frames(arms[:, s, j], arm_mask[:, s, j]) for j in range(3)]
        for parent, child in ((0, 1), (1, 2)):
            ok = arm_mask[:, s, parent] & arm_mask[:, s, child] & ~bad[parent]
            bad[child] = bad[child] | (segment_jump_frames(arms[:, s, parent], arms[:, s, child], ok) & ~bad[child])
        for j in range(3):
            values, valid = fill_gaps(arms[:, s, j], arm_mask[:, s, j] & ~bad[j], max_gap)
            arms[:, s, j] = savgol(values, valid, window)
            arm_mask[:, s, j] = valid
    fingers, finger_mask = demo.finger_positions.copy(), demo.finger_mask.copy()
    for s in range(2):
        for f in range(fingers.shape[2]):
            fingers[:, s, f] = savgol(fingers[:, s, f], finger_mask[:, s, f], window)
    rots, wrist_mask = demo.wrist_rotations.copy(), demo.wrist_mask.copy()
    for s in range(2):
        rots[:, s], wrist_mask[:, s], _ = continuous_rotations(rots[:, s], wrist_mask[:, s], max_gap, fps)
    meta = dict(demo.meta)
    meta["conditioned"] = True
    return Demonstration(fps, arms, arm_mask, rots, wrist_mask, fingers, finger_mask, name=demo.name, meta=meta)


ROTATION_JUMP = 1.0  # [rad] a wrist rotation this far from both neighbours is an outlier frame


def continuous_rotations(R: np.ndarray, ok: np.ndarray, max_gap: int, fps: float) -> tuple[np.ndarray, np.ndarray, int]:
    """Rotations ``(T, 3, 3)`` without isolated flips (more than :data:`ROTATION_JUMP` from both
    neighbours: repaired by interpolation), smoothed entry-wise and projected back onto rotations.

    Returns:
        ``(rotations, valid, repaired)``: NaN where not valid; the number of flipped frames.
    """
    ok = np.asarray(ok, bool) & np.isfinite(R).all(axis=(1, 2))
    steps = np.nan_to_num(rotation_steps(np.where(ok[:, None, None], R, np.nan)))  # (T-1,)
    jump = np.concatenate([[0.0], steps]) > ROTATION_JUMP  # turned away from the previous frame
    back = np.concatenate([steps, [0.0]]) > ROTATION_JUMP  # and away from the next
    flip = ok & jump & back
    values, valid = fill_gaps(R, ok & ~flip, max_gap)
    values = savgol(values, valid, window_frames(fps))
    return np.where(valid[:, None, None], orthonormalize(values), np.nan), valid, int(flip.sum())
