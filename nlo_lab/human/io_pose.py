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

- Arms from ``POSE_WORLD_LANDMARKS`` when present (``meta["depth"] = "world"``),
  unscaled to metres (x / width, y / height, z as stored). Otherwise from the image
  landmarks (``meta["depth"] = "image"``, with a warning), scaled so that the median
  shoulder distance is :data:`NOMINAL_SHOULDER_WIDTH` [m]. MediaPipe's image z of body
  landmarks is too noisy to use as depth (at its nominal scale, z * width, it raises the
  coefficient of variation of the upper-arm length from 0.10 to 0.28-0.32 on the shared
  recordings): the depth of elbow and wrist is instead reconstructed from the segment
  lengths (:func:`nlo_lab.human.conditioning.depth_from_lengths`): a segment whose
  image is shorter than the segment points out of the image plane. Each segment's length
  is the larger of its 90th-percentile image length and the body model's proportion of
  the shoulder width (upper arm 0.30 / 0.36, forearm 0.26 / 0.36, :mod:`nlo_lab.human.proportions`); the
  sign (towards or away from the camera) follows MediaPipe's z where it says clearly
  away (by more than :data:`DEPTH_SIGN_MARGIN`), else towards the camera (signing space
  is in front of the body).
- Conditioning (:mod:`nlo_lab.human.conditioning`), in the camera-aligned metric frame:
  outlier frames of each arm point (Hampel filter, and segment-length jumps of upper
  arm and forearm) are removed and, with the other gaps, interpolated; then every
  point is smoothed (Savitzky-Golay). ``meta["conditioning"]`` counts what was repaired.
- Body frame per frame: origin at the shoulder midpoint, Y from the right to the
  left shoulder, Z = the clip's "up" made orthogonal to Y, X = Y x Z (forward,
  towards the camera for a person facing it). "Up" never comes from the image axes
  blindly, so any camera roll (a sideways phone) gives the same demonstration. It is
  the confidence-weighted mean direction over the clip (per-frame directions would
  make the frame jitter) of, in order of preference (``meta["up_from"]``):
  ``"hips"``: hip centre -> shoulder centre, when the hips' median confidence is at
  least :data:`HIP_MIN_CONFIDENCE` (in signing videos they are often outside the
  image: MediaPipe then guesses them, with confidence 0.01-0.2);
  ``"face"``: shoulder centre -> ears' midpoint (the ears sit above the shoulders in an
  upright posture; else eyes, else nose, else the centre of the face mesh), in the
  image plane (a camera roll turns the image plane in itself; MediaPipe's depth of the
  face is unreliable: its world landmarks put the ears 50 degrees in front of the
  shoulders in one shared recording);
  ``"image"``: the image's up (-y), only when neither hips nor face are seen, with a
  warning: then the result is wrong for a rolled camera.
- Hands: the 21 hand landmarks relative to the hand's own wrist landmark, in pixels
  (z * width when z is on MediaPipe's normalised scale), scaled to metres with the
  same metres-per-pixel as the body (world: the ratio of the world to the image
  shoulder distance), rotated into the body frame and placed so that the hand's
  wrist coincides with the arm's wrist. Frames whose palm (wrist -> middle MCP) jumps
  in length are repaired like the arm's; the points are smoothed; the hand is then
  scaled about the wrist so that its median length (wrist -> middle fingertip along
  the finger) is :data:`HAND_PER_FOREARM` times the arm's median forearm (MediaPipe's
  hand scale is unrelated to the body's: hands measured 0.16-0.33 m). Wrist rotations
  that turn by more than :data:`ROTATION_JUMP` [rad] away from both neighbours are
  repaired, the others smoothed entry-wise and projected back onto rotations. Finger base = MCP (thumb: THUMB_MCP, point 2),
  tip = points 4, 8, 12, 16, 20. Wrist orientation from WRIST (0), INDEX_FINGER_MCP (5),
  MIDDLE_FINGER_MCP (9), PINKY_MCP (17) with :func:`wrist_frame_from_hand`.
- Missing data: a point is observed when its confidence is > :data:`MIN_CONFIDENCE`
  (a hand: all 21 points). Interior gaps of at most :data:`MAX_GAP_SECONDS`
  (rounded to frames) are linearly interpolated; longer gaps and gaps at the start or
  end are masked (NaN + mask False), never zeros.
- Only the first person of the file is read.
"""

from __future__ import annotations

import warnings

import numpy as np

from nlo_lab.errors import DemonstrationError
from nlo_lab.files import as_path
from nlo_lab.human import conditioning as cond
from nlo_lab.human import proportions
from nlo_lab.human.demonstration import ARM_JOINTS, SIDES, Demonstration
from nlo_lab.human.pose_file import MAX_HEADER_BYTES, MAX_PEOPLE, MAX_POSE_BYTES, MIN_CONFIDENCE, PoseComponents, read_pose_file
from nlo_lab.human.pose_landmarks import (
    DEPTH_SIGN_MARGIN,
    HIP_MIN_CONFIDENCE,
    NOMINAL_SHOULDER_WIDTH,
    condition_arms,
    face_centre,
    median_shoulder_distance,
    reconstruct_depth,
    up_direction,
)
from nlo_lab.human.transforms import body_frame_from_shoulders, check_arm_lengths, fill_gaps, wrist_frame_from_hand

__all__ = [
    "NOMINAL_SHOULDER_WIDTH",
    "MAX_GAP_SECONDS",
    "MIN_CONFIDENCE",
    "IMAGE_POSE_DEPTH_SCALE",
    "HAND_FINGER_POINTS",
    "HIP_MIN_CONFIDENCE",
    "HAND_PER_FOREARM",
    "ROTATION_JUMP",
    "DEPTH_SIGN_MARGIN",
    "MAX_PEOPLE",
    "MAX_HEADER_BYTES",
    "MAX_POSE_BYTES",
    "load_pose",
]

MAX_GAP_SECONDS = 0.25  # [s] longest gap of missing frames that is interpolated
IMAGE_POSE_DEPTH_SCALE = 0.0  # image z of body landmarks is not used (see the module docstring)
HAND_FINGER_POINTS = ((2, 4), (5, 8), (9, 12), (13, 16), (17, 20))  # (base, tip) landmark per finger, thumb..pinky
HAND_PER_FOREARM = proportions.HAND_LENGTH / proportions.FOREARM  # 0.19 / 0.26, a nominal adult's
ROTATION_JUMP = cond.ROTATION_JUMP  # [rad] a wrist rotation this far from both neighbours is an outlier frame
_HAND_WRIST, _HAND_INDEX, _HAND_MIDDLE, _HAND_PINKY = 0, 5, 9, 17
_WORLD_SHOULDER_RANGE = (0.15, 0.8)  # [m] plausible world shoulder distances; outside it the world scale is not trusted
_POSE = "POSE_LANDMARKS"
_WORLD = "POSE_WORLD_LANDMARKS"
_HANDS = {"left": "LEFT_HAND_LANDMARKS", "right": "RIGHT_HAND_LANDMARKS"}


def load_pose(path, condition: bool = True) -> Demonstration:
    """Read a MediaPipe Holistic ``.pose`` recording into a :class:`Demonstration` (see the module docstring).

    Args:
        path: the ``.pose`` file.
        condition: repair, smooth and scale as the module docstring says (default); False
            reads the landmarks as they are (gaps still interpolated, depth still
            reconstructed for image-only files): the raw geometry, for tests and comparison.

    Returns:
        The demonstration; ``meta`` records the source file name, the arm source
        component, the scale used, the up direction's origin and the hand coverage.

    Raises:
        DemonstrationError: unreadable or truncated file, no frames, fps <= 0, no pose
            component, a required landmark (shoulders, elbows, wrists) missing in every
            frame, NaN or inf in an observed landmark, an arm of zero length.
    """
    path = as_path(path)
    pose, data, mask, conf, fps = read_pose_file(path)
    T = data.shape[0]
    if T == 0:
        raise DemonstrationError("the recording has no frames", path=path, field="body.data")
    try:
        fps = float(fps)
    except (TypeError, ValueError):
        raise DemonstrationError(f"fps is not a number: {fps!r}", path=path, field="fps") from None
    if not np.isfinite(fps) or fps <= 0:
        raise DemonstrationError(f"fps must be > 0, got {fps}", path=path, field="fps")
    comps = PoseComponents(pose, data, mask, conf, path)
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
    img_width_px = median_shoulder_distance(img_ls, img_rs, img_sh_ok, slice(0, 2))
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
        width = median_shoulder_distance(pts["left", "shoulder"][0], pts["right", "shoulder"][0], sh_ok, slice(0, 3))
        if not width > 0:  # e.g. every world landmark at zero: no scale to take from them
            raise DemonstrationError("the world landmarks put both shoulders at one point", path=path, field=f"{_WORLD}/LEFT_SHOULDER")
        extra = 1.0
        if not (_WORLD_SHOULDER_RANGE[0] <= width <= _WORLD_SHOULDER_RANGE[1]):
            extra = NOMINAL_SHOULDER_WIDTH / width  # the stored world scale is implausible: fall back to the nominal width
            pts = {k: (v * extra, ok) for k, (v, ok) in pts.items()}
        world_xy = median_shoulder_distance(pts["left", "shoulder"][0], pts["right", "shoulder"][0], sh_ok, slice(0, 2))
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

    # outliers removed, gaps interpolated (long ones stay masked), then smoothed
    filled, repaired = condition_arms(pts, fps, max_gap, condition)
    depth = "world" if use_world else "image"
    if not use_world:
        zs = np.concatenate([v[ok][:, 2] for v, ok in image.values()])
        z_normalised = zs.size == 0 or np.abs(zs).max() <= 10.0  # MediaPipe's scale (like x / width), else pixels
        filled, lengths = reconstruct_depth(filled, image, (W if z_normalised and W > 0 else 1.0) * m_per_px)
        meta_scale["segment_lengths_m"] = lengths
        warnings.warn(f"{path.name}: no world landmarks: depth reconstructed from the image and the limb lengths "
                      "(less reliable than a recording with world landmarks)", UserWarning, stacklevel=2)

    # ---------------------------------------------------------------- body frame
    (ls, ls_ok), (rs, rs_ok) = filled["left", "shoulder"], filled["right", "shoulder"]
    face = face_centre(comps, source, use_world, unscale if use_world else flat, extra if use_world else 1.0, m_per_px)
    up, up_from = up_direction(ls, rs, ls_ok & rs_ok, hips, face)
    if up_from == "image":
        warnings.warn(f"{path.name}: neither the face nor the hips are seen: the body's up is taken from the image's "
                      "up; if the camera was rolled (a sideways phone), the demonstration is wrong", UserWarning, stacklevel=2)
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
        seen = seen & frame_ok
        palm_jump = cond.segment_jump_frames(rel_body[:, _HAND_WRIST], rel_body[:, _HAND_MIDDLE], seen) & condition
        rel_body, ok = fill_gaps(rel_body, seen & ~palm_jump, max_gap)
        if condition:
            rel_body = cond.savgol(rel_body, ok, cond.window_frames(fps))
        hand_len = np.linalg.norm(np.diff(rel_body[:, [0, 9, 10, 11, 12]], axis=1), axis=-1).sum(-1)  # (T,) along the middle finger
        scale = 1.0
        if condition and ok.any() and np.median(hand_len[ok]) > 0:
            try:
                fore = float(np.median(np.linalg.norm(arms[:, s, 2] - arms[:, s, 1], axis=-1)[arm_mask[:, s, 1] & arm_mask[:, s, 2]]))
            except ValueError:
                fore = float("nan")
            if np.isfinite(fore) and fore > 0:
                scale = HAND_PER_FOREARM * fore / float(np.median(hand_len[ok]))
        rel_body = rel_body * scale
        ok &= arm_mask[:, s, 2]
        hand = arms[:, s, 2][:, None] + rel_body  # (T, 21, 3) body frame, wrist pinned on the arm's wrist
        R = wrist_frame_from_hand(hand[:, _HAND_WRIST], hand[:, _HAND_INDEX], hand[:, _HAND_PINKY], hand[:, _HAND_MIDDLE])
        if condition:
            R, r_ok, rot_repaired = cond.continuous_rotations(R, ok, max_gap, fps)
            r_ok &= ok
        else:
            r_ok, rot_repaired = ok & np.isfinite(R).all(axis=(1, 2)), 0
        rots[:, s] = np.where(r_ok[:, None, None], R, np.nan)
        wrist_mask[:, s] = r_ok
        for f, (b, t) in enumerate(HAND_FINGER_POINTS):
            fingers[:, s, f, 0] = np.where(ok[:, None], hand[:, b], np.nan)
            fingers[:, s, f, 1] = np.where(ok[:, None], hand[:, t], np.nan)
            finger_mask[:, s, f] = ok
        hand_meta[side] = {"observed_frames": int(comps.observed[comp].all(axis=1).sum()), "valid_frames": int(ok.sum()),
                           "scale": round(float(scale), 4), "palm_jump_frames": int(palm_jump.sum()),
                           "rotation_repaired_frames": int(rot_repaired)}

    meta = {
        "source": path.name,
        "format": "pose",
        "arm_source": source,
        "metres_per_pixel": float(m_per_px),
        "up_from": up_from,
        "up_direction": [round(float(x), 4) for x in up],
        "depth": depth,
        "conditioning": repaired,
        "max_gap_frames": max_gap,
        "hands": hand_meta,
        **meta_scale,
    }
    demo = Demonstration.from_arrays(fps, arms, arm_mask, rots, wrist_mask, fingers, finger_mask,
                                     name=path.stem, meta=meta, path=path)
    check_arm_lengths(demo, path=path)
    return demo
