"""The data model of one human demonstration.

Frame: the body frame, origin at the centre of the two shoulders, X forward,
Y to the demonstrator's left, Z up. Units: metres, radians.

Missing or low-confidence points are explicit: each array has a boolean mask,
and a masked-out value is stored as NaN so that code which forgets the mask
fails loudly instead of silently retargeting to a zero.

Wrist frame convention (both hands): the columns of ``R_body_wrist`` are
x = from the wrist towards the middle-finger base (along the hand),
y = from the little-finger base towards the index base, made orthogonal to x,
z = x cross y. (For the right hand z is the back of the hand, for the left hand
the palm: the frame is a proper rotation on both sides.)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from nlo_lab.errors import DemonstrationError

__all__ = ["Demonstration", "SIDES", "ARM_JOINTS", "FINGERS", "FINGER_POINTS", "FPS_RANGE", "MAX_FRAMES", "MAX_COORDINATE",
           "ROTATION_TOLERANCE"]

SIDES = ("left", "right")
ARM_JOINTS = ("shoulder", "elbow", "wrist")
FINGERS = ("thumb", "index", "middle", "ring", "pinky")
FINGER_POINTS = ("base", "tip")  # base = metacarpophalangeal joint, tip = fingertip
# Frame rates a recording may state: from a 1 Hz time-lapse to a 1000 Hz motion-capture
# system (MediaPipe video runs at 15-60 Hz, the authors' gloves at about 15 Hz). Outside it
# the value is a broken or crafted header, and durations and velocities built on it are garbage.
FPS_RANGE = (1.0, 1000.0)
# Longest recording read or built: two hours at 60 fps (about 330 MB of float64 arrays).
# Readers check a file's declared size against it before they read the data.
MAX_FRAMES = 432_000
ROTATION_TOLERANCE = 1e-3  # largest |R^T R - I| entry (and |det R - 1|) of a valid wrist rotation
# Largest coordinate [m] a valid point may have in the body frame: a person's arm reaches about 1 m;
# a point 1 km away is a broken or crafted file (3e38 m overflows the objective's float32 to inf).
MAX_COORDINATE = 1000.0


def _side_index(side: str) -> int:
    if side not in SIDES:
        raise DemonstrationError(f"unknown side {side!r}; expected one of {SIDES}")
    return SIDES.index(side)


@dataclass
class Demonstration:
    """One recording of a demonstrator's two arms and hands.

    Attributes:
        fps: frames per second (> 0).
        arm_positions: ``(T, 2, 3, 3)`` [m]: side (left, right) x joint
            (shoulder, elbow, wrist) x xyz, in the body frame.
        arm_mask: ``(T, 2, 3)`` bool, True where the point was observed.
        wrist_rotations: ``(T, 2, 3, 3)`` rotation matrices ``R_body_wrist``.
        wrist_mask: ``(T, 2)`` bool.
        finger_positions: ``(T, 2, 5, 2, 3)`` [m]: side x finger (thumb..pinky)
            x (base, tip) x xyz.
        finger_mask: ``(T, 2, 5)`` bool, True where both base and tip are valid.
        name: a label (sequence or file name).
        meta: free-form provenance (source file, scenario, signer, ...).
        path: the file it was read from (set by the readers), named by errors about it later
            (retargeting, metrics); None for a demonstration built in memory.
    """

    fps: float
    arm_positions: np.ndarray
    arm_mask: np.ndarray
    wrist_rotations: np.ndarray
    wrist_mask: np.ndarray
    finger_positions: np.ndarray
    finger_mask: np.ndarray
    name: str = ""
    meta: dict[str, Any] = field(default_factory=dict)
    path: str | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        self.validate()

    @classmethod
    def from_arrays(
        cls,
        fps: float,
        arm_positions: np.ndarray,
        arm_mask: np.ndarray,
        wrist_rotations: np.ndarray,
        wrist_mask: np.ndarray,
        finger_positions: np.ndarray,
        finger_mask: np.ndarray,
        name: str = "",
        meta: dict[str, Any] | None = None,
        path=None,
    ) -> Demonstration:
        """Build and validate a demonstration; a validation error names ``path`` (the source file).

        Readers use this instead of the constructor so that an invalid field is
        reported together with the file it came from.
        """
        demo = object.__new__(cls)
        demo.fps = fps
        demo.arm_positions = arm_positions
        demo.arm_mask = arm_mask
        demo.wrist_rotations = wrist_rotations
        demo.wrist_mask = wrist_mask
        demo.finger_positions = finger_positions
        demo.finger_mask = finger_mask
        demo.name = name
        demo.meta = {} if meta is None else dict(meta)
        demo.path = None if path is None else str(path)
        demo.validate()
        return demo

    # ------------------------------------------------------------------ checks
    def validate(self, path=None) -> None:
        """Check fps, shapes, dtypes, finiteness, range and rotations; raise :class:`DemonstrationError` naming the field.

        fps must be a real number (not a bool, string or complex) in :data:`FPS_RANGE`;
        the arrays real numbers (booleans for the masks); every valid point within
        :data:`MAX_COORDINATE` metres of the body frame's origin on each axis; every valid wrist rotation
        a rotation matrix within :data:`ROTATION_TOLERANCE`. Errors name ``path`` (default: :attr:`path`).
        """
        if path is None:
            path = getattr(self, "path", None)
        if not isinstance(self.name, str):
            raise DemonstrationError(f"name must be text, got {type(self.name).__name__}", path=path, field="name")
        if not isinstance(self.meta, dict):
            raise DemonstrationError(f"meta must be a dict, got {type(self.meta).__name__}", path=path, field="meta")
        fps = self.fps
        if isinstance(fps, np.ndarray) and fps.shape == ():
            fps = fps[()]
        if isinstance(fps, (bool, np.bool_)) or not isinstance(fps, (int, float, np.integer, np.floating)):
            raise DemonstrationError(f"fps must be a real number, got {type(fps).__name__}", path=path, field="fps")
        fps = float(fps)
        if not FPS_RANGE[0] <= fps <= FPS_RANGE[1]:  # also false for NaN
            raise DemonstrationError(f"fps must be in [{FPS_RANGE[0]:g}, {FPS_RANGE[1]:g}], got {fps:g}", path=path, field="fps")
        self.fps = fps
        raw = np.asarray(self.arm_positions)
        if raw.dtype.kind not in "iuf":
            raise DemonstrationError(f"arm_positions must hold real numbers, got dtype {raw.dtype}", path=path, field="arm_positions")
        self.arm_positions = raw.astype(np.float64, copy=False)
        if self.arm_positions.ndim != 4 or self.arm_positions.shape[1:] != (2, 3, 3):
            raise DemonstrationError(
                f"arm_positions must be (T, 2, 3, 3), got {self.arm_positions.shape}", path=path, field="arm_positions"
            )
        T = self.arm_positions.shape[0]
        if T == 0:
            raise DemonstrationError("the demonstration has no frames", path=path, field="arm_positions")
        if T > MAX_FRAMES:
            raise DemonstrationError(f"{T} frames is more than the {MAX_FRAMES} this nlo_lab reads", path=path, field="arm_positions")
        expected = {
            "arm_mask": (T, 2, 3),
            "wrist_rotations": (T, 2, 3, 3),
            "wrist_mask": (T, 2),
            "finger_positions": (T, 2, 5, 2, 3),
            "finger_mask": (T, 2, 5),
        }
        for name, shape in expected.items():
            raw = np.asarray(getattr(self, name))
            kinds = "biu" if name.endswith("mask") else "iuf"
            if raw.dtype.kind not in kinds:
                raise DemonstrationError(f"{name} must hold {'booleans' if kinds == 'biu' else 'real numbers'}, got dtype {raw.dtype}",
                                         path=path, field=name)
            value = raw.astype(bool if name.endswith("mask") else np.float64, copy=False)
            if value.shape != shape:
                raise DemonstrationError(f"{name} must be {shape}, got {value.shape}", path=path, field=name)
            setattr(self, name, value)
        checks = (
            ("arm_positions", self.arm_positions, self.arm_mask[..., None]),
            ("wrist_rotations", self.wrist_rotations, self.wrist_mask[..., None, None]),
            ("finger_positions", self.finger_positions, self.finger_mask[..., None, None]),
        )
        for name, value, mask in checks:
            bad = ~np.isfinite(value) & np.broadcast_to(mask, value.shape)
            if bad.any():
                frame = int(np.argwhere(bad)[0][0])
                raise DemonstrationError(f"{name} holds NaN or inf where the mask says valid", path=path, frame=frame, field=name)
            if name != "wrist_rotations":
                far = np.abs(np.where(np.broadcast_to(mask, value.shape), value, 0.0)) > MAX_COORDINATE
                if far.any():
                    frame = int(np.argwhere(far)[0][0])
                    raise DemonstrationError(f"{name} holds a coordinate of {value[far][0]:.3g} m, beyond the {MAX_COORDINATE:g} m "
                                             "a recording may span (a broken or crafted file)", path=path, frame=frame, field=name)
            # Masked-out entries are NaN by convention (never silent zeros).
            value[~np.broadcast_to(mask, value.shape)] = np.nan
        R = self.wrist_rotations[self.wrist_mask]  # (N, 3, 3) the valid ones
        if len(R):
            off = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max(axis=(-1, -2))
            off = np.maximum(off, np.abs(np.linalg.det(R) - 1.0))
            bad = off > ROTATION_TOLERANCE
            if bad.any():
                t, s = np.argwhere(self.wrist_mask)[int(np.argmax(bad))]
                raise DemonstrationError(f"wrist rotation is not a rotation matrix (error {off[bad][0]:.3g})",
                                         path=path, frame=int(t), field=f"wrist_rotations/{SIDES[s]}")

    # ------------------------------------------------------------------ access
    def __len__(self) -> int:
        return int(self.arm_positions.shape[0])

    @property
    def duration(self) -> float:
        """Length in seconds."""
        return len(self) / self.fps

    def position(self, side: str, joint: str) -> np.ndarray:
        """``(T, 3)`` positions [m] of ``joint`` (shoulder/elbow/wrist) of arm ``side``."""
        if joint not in ARM_JOINTS:
            raise DemonstrationError(f"unknown arm joint {joint!r}; expected one of {ARM_JOINTS}")
        return self.arm_positions[:, _side_index(side), ARM_JOINTS.index(joint)]

    def position_mask(self, side: str, joint: str) -> np.ndarray:
        """``(T,)`` validity of :meth:`position`."""
        if joint not in ARM_JOINTS:
            raise DemonstrationError(f"unknown arm joint {joint!r}; expected one of {ARM_JOINTS}")
        return self.arm_mask[:, _side_index(side), ARM_JOINTS.index(joint)]

    def wrist_rotation(self, side: str) -> np.ndarray:
        """``(T, 3, 3)`` wrist orientations ``R_body_wrist``."""
        return self.wrist_rotations[:, _side_index(side)]

    def fingers(self, side: str) -> np.ndarray:
        """``(T, 5, 2, 3)`` finger base and tip positions [m], thumb..pinky."""
        return self.finger_positions[:, _side_index(side)]

    def arm_lengths(self, side: str) -> tuple[float, float]:
        """Median upper-arm and forearm lengths [m] over the valid frames."""
        s = _side_index(side)
        p, m = self.arm_positions[:, s], self.arm_mask[:, s]
        upper = np.linalg.norm(p[:, 1] - p[:, 0], axis=-1)[m[:, 0] & m[:, 1]]
        fore = np.linalg.norm(p[:, 2] - p[:, 1], axis=-1)[m[:, 1] & m[:, 2]]
        if upper.size == 0 or fore.size == 0:
            raise DemonstrationError(f"the {side} arm is never fully observed", path=self.path, field=f"{side}/arm")
        return float(np.median(upper)), float(np.median(fore))

    def slice(self, start: int, stop: int) -> Demonstration:
        """Frames ``start:stop`` as a new demonstration."""
        sl = slice(start, stop)
        return Demonstration(
            self.fps,
            self.arm_positions[sl].copy(),
            self.arm_mask[sl].copy(),
            self.wrist_rotations[sl].copy(),
            self.wrist_mask[sl].copy(),
            self.finger_positions[sl].copy(),
            self.finger_mask[sl].copy(),
            name=self.name,
            meta=dict(self.meta),
            path=self.path,
        )

    def __repr__(self) -> str:
        return f"Demonstration(name={self.name!r}, frames={len(self)}, fps={self.fps:g})"
