"""The ``.pose`` reader: MediaPipe Holistic recordings (library ``pose-format``), from the file's bytes to a demonstration.

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

The file (section "the file"): a crafted file of a few kB must not make us read or allocate
gigabytes. It must be a regular file of at most :data:`MAX_POSE_BYTES`
(:mod:`nlo_lab.files`); its header is parsed alone first (at most :data:`MAX_HEADER_BYTES`)
and the body's declared frames, people and points are checked against the file's length
before pose-format parses the body, for every version (0.0 walked frame by frame, 0.1 and
0.2 from their counts): a truncated or padded file is an error, never fewer frames.

From landmarks to arms in metres (section "landmarks"): :func:`condition_arms` (outliers,
gaps, smoothing), :func:`reconstruct_depth` (elbow and wrist depth from the segment lengths
when the file has no world landmarks), :func:`face_centre` and :func:`up_direction` (the
clip's up, from the hips, else the face, else the image).
"""

from __future__ import annotations

import struct
import warnings
from pathlib import Path

import numpy as np

from nlo_lab.errors import DemonstrationError
from nlo_lab.files import as_path, format_size, read_input_bytes
from nlo_lab.human import conditioning as cond
from nlo_lab.human import proportions
from nlo_lab.human.demonstration import ARM_JOINTS, MAX_FRAMES, SIDES, Demonstration
from nlo_lab.human.transforms import body_frame_from_shoulders, check_arm_lengths, fill_gaps, wrist_frame_from_hand

__all__ = [
    "MAX_POSE_BYTES",
    "MAX_HEADER_BYTES",
    "MAX_PEOPLE",
    "MIN_CONFIDENCE",
    "NOMINAL_SHOULDER_WIDTH",
    "MAX_GAP_SECONDS",
    "IMAGE_POSE_DEPTH_SCALE",
    "HAND_FINGER_POINTS",
    "HIP_MIN_CONFIDENCE",
    "HAND_PER_FOREARM",
    "ROTATION_JUMP",
    "DEPTH_SIGN_MARGIN",
    "check_pose_sizes",
    "read_pose_file",
    "PoseComponents",
    "median_shoulder_distance",
    "condition_arms",
    "reconstruct_depth",
    "face_centre",
    "up_direction",
    "load_pose",
]


# ----------------------------------------------------------------------------- the file
MIN_CONFIDENCE = 0.0  # a landmark is observed when its confidence is above this
# Sizes a .pose file may have or its header declare, checked before the body is parsed.
MAX_POSE_BYTES = 256 << 20  # the file: 29,000 frames of Holistic with the face mesh (16 min at 30 fps), 150,000 without
MAX_PEOPLE = 64  # people per frame (only the first is read)
MAX_HEADER_BYTES = 1 << 20  # a Holistic header with the face mesh is about 10 kB


def _fail(path, message):
    raise DemonstrationError(message, path=path)


def check_pose_sizes(path: Path, raw: bytes) -> None:
    """Refuse a file whose header declares more than we read, or a body its length does not hold exactly.

    ``raw`` is the whole file (at most :data:`MAX_POSE_BYTES`). Reads only the header and the
    body's counts, for every version pose-format reads (0.0, 0.1, 0.2; others are refused):
    frames at most :data:`~nlo_lab.human.demonstration.MAX_FRAMES`, people at most
    :data:`MAX_PEOPLE`, and the declared frames x people x points x (dims + confidence)
    float32 values must be exactly what the file holds after its header, so a truncated
    file (a version 0.1 file cut between frames too) is an error, never fewer frames.
    Version 0.0 stores each frame's people separately, and a frame without a person
    still makes pose-format allocate a whole frame: its frames are walked one by one and
    the values the reader will allocate are bounded as if they were stored.
    """
    from pose_format.pose_header import PoseHeader
    from pose_format.utils.reader import BufferReader

    reader = BufferReader(raw[:MAX_HEADER_BYTES])
    try:
        header = PoseHeader.read(reader)
        version = round(float(header.version), 3)
        points = sum(len(c.points) for c in header.components)
        dims = max(len(c.format) for c in header.components) - 1  # as pose-format's body reader counts them
    except Exception as err:  # a header pose-format cannot parse, or longer than the limit
        too_long = len(raw) > MAX_HEADER_BYTES
        _fail(path, f"not a readable .pose file ({f'no header within {MAX_HEADER_BYTES} bytes' if too_long else f'{type(err).__name__}: {err}'})")
    start = reader.read_offset
    size = len(raw)
    try:
        if version == 0.2:
            _fps, frames, people = struct.unpack_from("<fIH", raw, start)
            body_start = start + struct.calcsize("<fIH")
        elif version == 0.1:
            _fps, declared, people = struct.unpack_from("<HHH", raw, start)
            body_start = start + struct.calcsize("<HHH")
            per_frame = people * points * (dims + 1) * 4
            # pose-format takes the frames from the file's length; the header's count is 16-bit
            frames = (size - body_start) // per_frame if per_frame else 0
            if per_frame and (size - body_start) % per_frame == 0 and frames % 65536 != declared:
                _fail(path, f"truncated or padded: the header declares {declared} frames, the body holds {frames}")
        elif version == 0.0:
            frames, people, body_start = _walk_v0_0(path, raw, start, header)
        else:
            _fail(path, f"unsupported .pose version {header.version:g} (pose-format writes 0.0, 0.1 and 0.2)")
    except struct.error:
        _fail(path, "truncated: the file ends inside the body's counts")
    if frames > MAX_FRAMES:
        _fail(path, f"declares {frames} frames, more than the {MAX_FRAMES} this nlo_lab reads")
    if people > MAX_PEOPLE:
        _fail(path, f"declares {people} people per frame, more than {MAX_PEOPLE}")
    body = frames * people * points * (dims + 1) * 4
    if version != 0.0 and body != size - body_start:
        _fail(path, f"truncated or padded: the header declares {frames} frames x {people} people x {points} points "
                    f"({body} bytes), but the file holds {size - body_start} bytes after its header")
    if body > MAX_POSE_BYTES:
        _fail(path, f"declares {frames} frames x {people} people x {points} points ({format_size(body)} of values), "
                    f"more than the {format_size(MAX_POSE_BYTES)} a .pose file may hold")


def _walk_v0_0(path: Path, raw: bytes, start: int, header) -> tuple[int, int, int]:
    """Frames and people (at least 1: pose-format fills a frame without a person) of a version 0.0 body, walked.

    Each frame: people (uint16), then per person an id (int16) and each component's
    points x format float32 values. The walk must end exactly at the end of the file.
    """
    _fps, frames = struct.unpack_from("<HH", raw, start)
    offset = start + 4
    person = 2 + 4 * sum(len(c.points) * len(c.format) for c in header.components)
    most = 1
    for t in range(frames):
        (people,) = struct.unpack_from("<H", raw, offset)
        if people > MAX_PEOPLE:
            _fail(path, f"frame {t} declares {people} people, more than {MAX_PEOPLE}")
        most = max(most, people)
        offset += 2 + people * person
        if offset > len(raw):
            _fail(path, f"truncated: the file ends inside frame {t} of the {frames} its header declares")
    if offset != len(raw):
        _fail(path, f"padded: {len(raw) - offset} bytes follow the {frames} frames its header declares")
    return frames, 1, start + 4  # pose-format keeps the first person only


def read_pose_file(path: Path):
    """The file's ``Pose`` and its arrays: ``(pose, data (T, P, N, D), mask, confidence (T, P, N), fps)``.

    The file is checked first (:func:`nlo_lab.files.read_input_bytes`: a regular file of at most
    :data:`MAX_POSE_BYTES`), then its sizes (:func:`check_pose_sizes`), then parsed.
    """
    try:
        from pose_format import Pose
    except ImportError as err:  # pragma: no cover - a declared dependency
        raise DemonstrationError(f"reading .pose files needs the pose-format package ({err})", path=path) from None
    raw = read_input_bytes(path, kind=".pose", max_bytes=MAX_POSE_BYTES, error=DemonstrationError)
    check_pose_sizes(path, raw)  # before the body is parsed or allocated
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


class PoseComponents:
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


# ----------------------------------------------------------------------------- landmarks
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


# ----------------------------------------------------------------------------- the reader
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
