"""The one switch between the readable code and its faster evaluations.

Some computations have a fast path that gives the same numbers as the code a
learner reads, only sooner, at some sizes: the objective (numpy terms with a
written-out gradient), the frozen decoder (numpy layers with a written-out
gradient), the capsule distances (numpy arithmetic for few pairs; only the
pairs that may be near, in the objective), and forward kinematics (pointer
jumping for small batches; a written-out gradient of mapped points). Each asks this module whether to take its fast path, so the size
thresholds live here and nowhere else::

    from nlo_lab import backend

    with backend.reference():  # every fast path off: the readable code runs
        result = retarget(demo, robot)

    with backend.use(objective_max_frames=0):  # one path off, the others as usual
        ...

The thresholds are the measured crossovers on one CPU thread (sources beside
each field). The setting is process-wide (worker threads see it too); the
context managers restore the previous one on exit. An explicit argument at a
call site (``Objective(fused=True)``) wins over the switch.
"""

from __future__ import annotations

import dataclasses
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from nlo_lab.errors import SettingsError
from nlo_lab.settings import check_int

__all__ = [
    "Backend",
    "current",
    "use",
    "reference",
    "numpy_objective",
    "numpy_decoder",
    "numpy_collision",
    "fk_pointer_jumping",
    "analytic_fk_gradient",
    "cull_far_pairs",
]


@dataclass(frozen=True)
class Backend:
    """Sizes up to which each fast path runs (0 = never), and the master switch.

    Attributes:
        objective_max_frames: frames up to which the objective's terms run in
            numpy (:mod:`nlo_lab.objective.numpy_backend`). YuMi, forward + backward:
            1 frame 0.70 vs 1.18 ms (torch), 32: 2.0 vs 2.3 ms, 64: equal,
            200: 7.7 vs 7.2 ms.
        decoder_max_batch: batch up to which the frozen decoder runs in numpy
            (:mod:`nlo_lab.model.numpy_backend`). YuMi, forward + backward: batch 1
            266 vs 473 us (torch), 170: 15.4 vs 2.6 ms (numpy's stacked small
            matmuls do not batch).
        collision_numpy_max_pairs: capsule pairs (frames x pairs) up to which the
            segment distances run in numpy; crossover about 3000 pairs.
        fk_jump_max_work: batch x tree depth up to which FK composes the link
            frames by pointer jumping (few small matmuls) instead of level by level.
        enabled: ``False`` turns every fast path off, whatever the sizes.
    """

    objective_max_frames: int = 64
    decoder_max_batch: int = 8
    collision_numpy_max_pairs: int = 4096
    fk_jump_max_work: int = 128
    enabled: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.enabled, bool):
            raise SettingsError(f"backend enabled must be True or False, got {self.enabled!r}")
        for f in dataclasses.fields(self):
            if f.name != "enabled":
                object.__setattr__(self, f.name, check_int(f"backend {f.name}", getattr(self, f.name), minimum=0))


_lock = threading.Lock()
_current = Backend()


def current() -> Backend:
    """The backend in force."""
    return _current


@contextmanager
def use(**changes) -> Iterator[Backend]:
    """Within the block, the current backend with ``changes`` (fields of :class:`Backend`).

    Raises:
        SettingsError: an unknown field or a bad value.
    """
    global _current
    unknown = sorted(set(changes) - {f.name for f in dataclasses.fields(Backend)})
    if unknown:
        raise SettingsError(f"unknown backend setting(s) {unknown}; expected fields of nlo_lab.backend.Backend")
    with _lock:
        previous = _current
        _current = dataclasses.replace(previous, **changes)
    try:
        yield _current
    finally:
        with _lock:
            _current = previous


@contextmanager
def reference() -> Iterator[Backend]:
    """Within the block every fast path is off: the readable code runs (same numbers, slower)."""
    with use(enabled=False) as b:
        yield b


def numpy_objective(frames: int) -> bool:
    """Whether an objective over ``frames`` frames (on the CPU) takes the numpy terms."""
    return _current.enabled and frames <= _current.objective_max_frames


def numpy_decoder(batch: int) -> bool:
    """Whether a frozen decoder at ``batch`` (on the CPU) takes the numpy layers."""
    return _current.enabled and batch <= _current.decoder_max_batch


def numpy_collision(pairs: int) -> bool:
    """Whether ``pairs`` segment distances (on the CPU) take the numpy arithmetic."""
    return _current.enabled and pairs <= _current.collision_numpy_max_pairs


def fk_pointer_jumping(work: int) -> bool:
    """Whether FK with ``work`` = batch x tree depth composes by pointer jumping."""
    return _current.enabled and work <= _current.fk_jump_max_work


def analytic_fk_gradient() -> bool:
    """Whether mapped FK points get their written-out gradient (else autograd through FK)."""
    return _current.enabled


def cull_far_pairs() -> bool:
    """Whether the objective's torch path measures only the capsule pairs that may be within their margin."""
    return _current.enabled
