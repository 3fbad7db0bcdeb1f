"""Reader of MediaPipe Holistic recordings in the ``.pose`` format (library ``pose-format``).

What the file holds (pose-format's Holistic converter): components
``POSE_LANDMARKS`` (33 points, or 8 upper-body points in older files),
``LEFT_HAND_LANDMARKS`` / ``RIGHT_HAND_LANDMARKS`` (21 points each), optionally
``POSE_WORLD_LANDMARKS`` (33) and a face. Image landmarks are stored as
``(x * width, y * height, z)`` (pixels; z on MediaPipe's relative scale), world
landmarks likewise ``(x * width, y * height, z)`` although MediaPipe gives them in
metres; the axes are the image's: x right, y down, z away from the camera (a
right-handed frame). A missing point has confidence 0. MediaPipe's LEFT/RIGHT are
the demonstrator's left/right (a recording of a mirrored video would swap them;
nothing in the landmarks can tell).

Conversion (documented choices):

- Arms from ``POSE_WORLD_LANDMARKS`` when present, unscaled to metres
  (x / width, y / height, z as stored). Otherwise from the image landmarks in the
  image plane only, scaled so that the median shoulder distance is
  :data:`NOMINAL_SHOULDER_WIDTH` [m]. The image z of body landmarks is dropped
  (:data:`IMAGE_POSE_DEPTH_SCALE` = 0): on the shared recordings, adding it at
  MediaPipe's nominal scale (z * width) raises the coefficient of variation of the
  upper-arm length from 0.10 to 0.28-0.32.
- Body frame per frame: origin at the shoulder midpoint, Y from the right to the
  left shoulder, Z = the clip's "up" made orthogonal to Y, X = Y x Z (forward,
  towards the camera for a person facing it). "Up" is the confidence-weighted mean
  direction hip centre -> shoulder centre over the clip when the hips are present
  (per-frame hips would make the frame jitter: in signing videos they are often
  outside the image, with low confidence), else the image's up (-y).
- Hands: the 21 hand landmarks relative to the hand's own wrist landmark, in pixels
  (z * width when z is on MediaPipe's normalised scale), scaled to metres with the
  same metres-per-pixel as the body (world: the ratio of the world to the image
  shoulder distance), rotated into the body frame and placed so that the hand's
  wrist coincides with the arm's wrist. Finger base = MCP (thumb: THUMB_MCP, point 2),
  tip = points 4, 8, 12, 16, 20. Wrist orientation from WRIST (0), INDEX_FINGER_MCP (5),
  MIDDLE_FINGER_MCP (9), PINKY_MCP (17) with :func:`wrist_frame_from_hand`.
- Missing data: a point is observed when its confidence is > :data:`MIN_CONFIDENCE`
  (a hand: all 21 points). Interior gaps of at most :data:`MAX_GAP_SECONDS`
  (rounded to frames) are linearly interpolated; longer gaps and gaps at the start or
  end are masked (NaN + mask False), never zeros.
- Only the first person of the file is read.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nlo_lab.errors import DemonstrationError
from nlo_lab.human.demonstration import ARM_JOINTS, SIDES, Demonstration
from nlo_lab.human.transforms import body_frame_from_shoulders, check_arm_lengths, fill_gaps, wrist_frame_from_hand

__all__ = [
    "NOMINAL_SHOULDER_WIDTH",
    "MAX_GAP_SECONDS",
    "MIN_CONFIDENCE",
    "IMAGE_POSE_DEPTH_SCALE",
    "HAND_FINGER_POINTS",
    "load_pose",
]

NOMINAL_SHOULDER_WIDTH = 0.36  # [m] shoulder-joint to shoulder-joint of an adult (scale of image-only files)
MAX_GAP_SECONDS = 0.25  # [s] longest gap of missing frames that is interpolated
MIN_CONFIDENCE = 0.0  # a landmark is observed when its confidence is above this
IMAGE_POSE_DEPTH_SCALE = 0.0  # image z of body landmarks is not used (see the module docstring)
HAND_FINGER_POINTS = ((2, 4), (5, 8), (9, 12), (13, 16), (17, 20))  # (base, tip) landmark per finger, thumb..pinky
_HAND_WRIST, _HAND_INDEX, _HAND_MIDDLE, _HAND_PINKY = 0, 5, 9, 17
_WORLD_SHOULDER_RANGE = (0.15, 0.8)  # [m] plausible world shoulder distances; outside it the world scale is not trusted
_POSE = "POSE_LANDMARKS"
_WORLD = "POSE_WORLD_LANDMARKS"
_HANDS = {"left": "LEFT_HAND_LANDMARKS", "right": "RIGHT_HAND_LANDMARKS"}
_IMAGE_UP = np.array([0.0, -1.0, 0.0])  # image y points down


def _read(path: Path):
    try:
        from pose_format import Pose
    except ImportError as err:  # pragma: no cover - a declared dependency
        raise DemonstrationError(f"reading .pose files needs the pose-format package ({err})", path=path) from None
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise DemonstrationError("no such file", path=path) from None
    except OSError as err:
        raise DemonstrationError(f"cannot read the file ({err})", path=path) from None
    if not raw:
        raise DemonstrationError("the file is empty", path=path)
    try:
        pose = Pose.read(raw)
        data = np.ma.getdata(pose.body.data)
        mask = np.ma.getmaskarray(pose.body.data)
        conf = np.asarray(pose.body.confidence)
        fps = pose.body.fps
    except Exception as err:  # pose-format raises many types on a truncated or foreign file
        raise DemonstrationError(f"not a readable .pose file ({type(err).__name__}: {err})", path=path) from None
    expected = sum(len(c.points) for c in pose.header.components)
    if data.ndim != 4 or data.shape[2] != expected or data.shape[3] not in (2, 3) or conf.shape != data.shape[:3]:
        raise DemonstrationError(
            f"body data of shape {data.shape} (confidence {conf.shape}) does not match the header's {expected} points",
            path=path, field="body.data",
        )
    return pose, data, mask, conf, fps


class _Components:
    """The first person's points per component: values ``(T, P, 3)`` and observed ``(T, P)``."""

    def __init__(self, pose, data, mask, conf, path: Path):
        self.path = path
        self.names: dict[str, list[str]] = {}
        self.values: dict[str, np.ndarray] = {}
        self.observed: dict[str, np.ndarray] = {}
        self.confidence: dict[str, np.ndarray] = {}
        if data.shape[1] == 0:
            raise DemonstrationError("the file holds no person", path=path, field="body.data")
        start = 0
        for comp in pose.header.components:
            n = len(comp.points)
            v = np.asarray(data[:, 0, start : start + n], dtype=np.float64)
            if v.shape[-1] == 2:
                v = np.concatenate([v, np.zeros(v.shape[:-1] + (1,))], axis=-1)
            c = np.asarray(conf[:, 0, start : start + n], dtype=np.float64)
            seen = (c > MIN_CONFIDENCE) & ~mask[:, 0, start : start + n].any(axis=-1)
            bad = seen & ~np.isfinite(v).all(axis=-1)
            if bad.any():
                t, p = np.argwhere(bad)[0]
                raise DemonstrationError("NaN or inf in an observed landmark", path=path, frame=int(t),
                                         field=f"{comp.name}/{comp.points[p]}")
            self.names[comp.name] = list(comp.points)
            self.values[comp.name], self.observed[comp.name], self.confidence[comp.name] = v, seen, c
            start += n

    def point(self, component: str, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if name not in self.names[component]:
            raise DemonstrationError(f"the {component} component has no {name} point", path=self.path, field=f"{component}/{name}")
        i = self.names[component].index(name)
        return self.values[component][:, i], self.observed[component][:, i], self.confidence[component][:, i]


def _median_shoulder_distance(ls: np.ndarray, rs: np.ndarray, ok: np.ndarray, dims: slice) -> float:
    d = np.linalg.norm((ls - rs)[ok][:, dims], axis=-1)
    return float(np.median(d)) if d.size else float("nan")


def load_pose(path) -> Demonstration:
    """Read a MediaPipe Holistic ``.pose`` recording into a :class:`Demonstration` (see the module docstring).

    Args:
        path: the ``.pose`` file.

    Returns:
        The demonstration; ``meta`` records the source file name, the arm source
        component, the scale used, the up direction's origin and the hand coverage.

    Raises:
        DemonstrationError: unreadable or truncated file, no frames, fps <= 0, no pose
            component, a required landmark (shoulders, elbows, wrists) missing in every
            frame, NaN or inf in an observed landmark, an arm of zero length.
    """
    path = Path(path)
    pose, data, mask, conf, fps = _read(path)
    T = data.shape[0]
    if T == 0:
        raise DemonstrationError("the recording has no frames", path=path, field="body.data")
    try:
        fps = float(fps)
    except (TypeError, ValueError):
        raise DemonstrationError(f"fps is not a number: {fps!r}", path=path, field="fps") from None
    if not np.isfinite(fps) or fps <= 0:
        raise DemonstrationError(f"fps must be > 0, got {fps}", path=path, field="fps")
    comps = _Components(pose, data, mask, conf, path)
    if _POSE not in comps.names:
        raise DemonstrationError(f"no {_POSE} component (found {sorted(comps.names)})", path=path, field=_POSE)
    W, H = float(pose.header.dimensions.width), float(pose.header.dimensions.height)
    max_gap = int(round(MAX_GAP_SECONDS * fps))

    # ---------------------------------------------------------------- arm points in a camera-aligned metric frame
    image = {}  # (side, joint) -> (values px (T, 3), observed (T,))
    for side in SIDES:
        for joint in ARM_JOINTS:
            v, ok, _ = comps.point(_POSE, f"{side.upper()}_{joint.upper()}")
            if not ok.any():
                raise DemonstrationError("required landmark missing in every frame", path=path, field=f"{_POSE}/{side.upper()}_{joint.upper()}")
            image[side, joint] = v, ok
    img_ls, img_rs = image["left", "shoulder"][0], image["right", "shoulder"][0]
    img_sh_ok = image["left", "shoulder"][1] & image["right", "shoulder"][1]
    img_width_px = _median_shoulder_distance(img_ls, img_rs, img_sh_ok, slice(0, 2))
    if not img_width_px > 0:
        raise DemonstrationError("the shoulders are never apart in the image", path=path, field=f"{_POSE}/LEFT_SHOULDER")

    use_world = _WORLD in comps.names and all(
        f"{s.upper()}_{j.upper()}" in comps.names[_WORLD] for s in SIDES for j in ARM_JOINTS
    )
    meta_scale: dict = {}
    if use_world:
        source = _WORLD
        unscale = np.array([1.0 / W if W > 0 else 1.0, 1.0 / H if H > 0 else 1.0, 1.0])
        pts = {}
        for side in SIDES:
            for joint in ARM_JOINTS:
                v, ok, _ = comps.point(_WORLD, f"{side.upper()}_{joint.upper()}")
                if not ok.any():
                    raise DemonstrationError("required landmark missing in every frame", path=path, field=f"{_WORLD}/{side.upper()}_{joint.upper()}")
                pts[side, joint] = v * unscale, ok
        sh_ok = pts["left", "shoulder"][1] & pts["right", "shoulder"][1]
        width = _median_shoulder_distance(pts["left", "shoulder"][0], pts["right", "shoulder"][0], sh_ok, slice(0, 3))
        extra = 1.0
        if not (_WORLD_SHOULDER_RANGE[0] <= width <= _WORLD_SHOULDER_RANGE[1]):
            extra = NOMINAL_SHOULDER_WIDTH / width  # the stored world scale is implausible: fall back to the nominal width
            pts = {k: (v * extra, ok) for k, (v, ok) in pts.items()}
        world_xy = _median_shoulder_distance(pts["left", "shoulder"][0], pts["right", "shoulder"][0], sh_ok, slice(0, 2))
        m_per_px = world_xy / img_width_px
        meta_scale = {"scale": "world landmarks / frame size" if extra == 1.0 else "world landmarks rescaled to the nominal shoulder width",
                      "world_shoulder_width_m": float(width * extra)}
        hip_names = [n for n in ("LEFT_HIP", "RIGHT_HIP") if n in comps.names[_WORLD]]
        hips = [(comps.point(_WORLD, n)[0] * unscale * extra, comps.point(_WORLD, n)[2] * comps.point(_WORLD, n)[1]) for n in hip_names]
    else:
        source = _POSE
        m_per_px = NOMINAL_SHOULDER_WIDTH / img_width_px
        flat = np.array([m_per_px, m_per_px, m_per_px * IMAGE_POSE_DEPTH_SCALE])
        pts = {k: (v * flat, ok) for k, (v, ok) in image.items()}
        meta_scale = {"scale": f"image shoulder distance = nominal {NOMINAL_SHOULDER_WIDTH} m"}
        hip_names = [n for n in ("LEFT_HIP", "RIGHT_HIP") if n in comps.names[_POSE]]
        hips = [(comps.point(_POSE, n)[0] * flat, comps.point(_POSE, n)[2] * comps.point(_POSE, n)[1]) for n in hip_names]

    # short gaps of each arm point are interpolated, long ones stay masked
    filled = {k: fill_gaps(v, ok, max_gap) for k, (v, ok) in pts.items()}

    # ---------------------------------------------------------------- body frame
    (ls, ls_ok), (rs, rs_ok) = filled["left", "shoulder"], filled["right", "shoulder"]
    up, up_from = _IMAGE_UP, "image"
    if len(hips) == 2:
        (lh, lw), (rh, rw) = hips
        vec = (ls + rs) / 2 - (lh + rh) / 2
        n = np.linalg.norm(vec, axis=-1, keepdims=True)
        w = np.minimum(lw, rw) * (ls_ok & rs_ok) * (n[:, 0] > 1e-9)
        if w.sum() > 0:
            mean = np.nansum(np.where(w[:, None] > 0, vec / np.where(n > 1e-9, n, 1.0), 0.0) * w[:, None], axis=0)
            mean /= np.linalg.norm(mean)
            if mean @ _IMAGE_UP > 0.5:  # within 60 degrees of the image's up: trust the hips
                up, up_from = mean, "hips"
    origin, R_src_body = body_frame_from_shoulders(ls, rs, up)  # (T, 3), (T, 3, 3)
    frame_ok = ls_ok & rs_ok & np.isfinite(R_src_body).all(axis=(1, 2))
    R_body_src = np.swapaxes(R_src_body, 1, 2)

    arms = np.full((T, 2, 3, 3), np.nan)
    arm_mask = np.zeros((T, 2, 3), dtype=bool)
    for s, side in enumerate(SIDES):
        for j, joint in enumerate(ARM_JOINTS):
            v, ok = filled[side, joint]
            ok = ok & frame_ok
            body = np.einsum("tij,tj->ti", R_body_src, v - origin)
            arms[:, s, j] = np.where(ok[:, None], body, np.nan)
            arm_mask[:, s, j] = ok
    for s, side in enumerate(SIDES):
        for j, joint in enumerate(ARM_JOINTS):
            if not arm_mask[:, s, j].any():
                raise DemonstrationError("required landmark never observed together with both shoulders",
                                         path=path, field=f"{source}/{side.upper()}_{joint.upper()}")

    # ---------------------------------------------------------------- hands
    rots = np.full((T, 2, 3, 3), np.nan)
    wrist_mask = np.zeros((T, 2), dtype=bool)
    fingers = np.full((T, 2, 5, 2, 3), np.nan)
    finger_mask = np.zeros((T, 2, 5), dtype=bool)
    hand_meta = {}
    for s, side in enumerate(SIDES):
        comp = _HANDS[side]
        if comp not in comps.names or len(comps.names[comp]) != 21:
            hand_meta[side] = {"observed_frames": 0, "valid_frames": 0}
            continue
        v, seen = comps.values[comp], comps.observed[comp].all(axis=1)  # (T, 21, 3), (T,)
        rel = v - v[:, :1]  # relative to the hand's wrist landmark
        z_normalised = not seen.any() or np.abs(v[seen][..., 2]).max() <= 10.0
        rel_m = rel * np.array([m_per_px, m_per_px, m_per_px * (W if z_normalised and W > 0 else 1.0)])
        rel_body = np.einsum("tij,tpj->tpi", R_body_src, np.where(seen[:, None, None], rel_m, 0.0))
        rel_body, ok = fill_gaps(rel_body, seen & frame_ok, max_gap)
        ok &= arm_mask[:, s, 2]
        hand = arms[:, s, 2][:, None] + rel_body  # (T, 21, 3) body frame, wrist pinned on the arm's wrist
        R = wrist_frame_from_hand(hand[:, _HAND_WRIST], hand[:, _HAND_INDEX], hand[:, _HAND_PINKY], hand[:, _HAND_MIDDLE])
        r_ok = ok & np.isfinite(R).all(axis=(1, 2))
        rots[:, s] = np.where(r_ok[:, None, None], R, np.nan)
        wrist_mask[:, s] = r_ok
        for f, (b, t) in enumerate(HAND_FINGER_POINTS):
            fingers[:, s, f, 0] = np.where(ok[:, None], hand[:, b], np.nan)
            fingers[:, s, f, 1] = np.where(ok[:, None], hand[:, t], np.nan)
            finger_mask[:, s, f] = ok
        hand_meta[side] = {"observed_frames": int(seen.sum()), "valid_frames": int(ok.sum())}

    meta = {
        "source": path.name,
        "format": "pose",
        "arm_source": source,
        "metres_per_pixel": float(m_per_px),
        "up_from": up_from,
        "max_gap_frames": max_gap,
        "hands": hand_meta,
        **meta_scale,
    }
    demo = Demonstration.from_arrays(fps, arms, arm_mask, rots, wrist_mask, fingers, finger_mask,
                                     name=path.stem, meta=meta, path=path)
    check_arm_lengths(demo, path=path)
    return demo
