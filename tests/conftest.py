"""Fixtures shared by the test modules.

- ``shared_file`` / ``shared_pose``: files of ``../shared`` beside the checkout (the real
  recordings and the founding reference). A user's clone does not have that folder: a test
  that needs it is skipped with the path it looked for.
- ``robot64``: a robot loaded once per session in float64 (for gradient and agreement checks);
  ``each_robot64``: each shipped robot in float64 in turn (a module's tests run once per robot);
  ``random_angles``: random angles inside a robot's limits.
- ``nao``, ``robots``: robots as the package loads them (float32), once per module.

A test module may still define a fixture of the same name; pytest then uses the module's.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from pathlib import Path

import pytest
import torch

from nlo_lab.robot import Robot, load_robot

SHARED = Path(__file__).resolve().parents[2] / "shared"  # beside the checkout (and in CI), never in a user's clone
SHARED_POSE = SHARED / "data" / "pose"  # the real MediaPipe recordings


def _shared(path: Path) -> Path:
    if not path.exists():
        pytest.skip(f"shared file not available at {path}")
    return path


@pytest.fixture(scope="session")
def shared_file() -> Callable[..., Path]:
    """``shared_file("reference", "ROBOT_FACTS.md")`` -> the path under ``../shared``, or skip."""
    return lambda *parts: _shared(SHARED.joinpath(*parts))


@pytest.fixture(scope="session")
def shared_pose() -> Callable[[str], Path]:
    """``shared_pose("holistic_world_97f.pose")`` -> a shared real recording, or skip."""
    return lambda name: _shared(SHARED_POSE / name)


@functools.cache
def _robot64(name: str) -> Robot:
    return load_robot(name).to(dtype=torch.float64)


@pytest.fixture(scope="session")
def robot64() -> Callable[[str], Robot]:
    """``robot64("yumi")`` -> the robot in float64, loaded once per session (tests must not change it)."""
    return _robot64


@pytest.fixture(scope="module", params=("yumi", "nao", "pepper"))
def each_robot64(request) -> Robot:
    """Each shipped robot in float64, one after the other."""
    return _robot64(request.param)


@pytest.fixture(scope="session")
def random_angles() -> Callable[[Robot, int, int], torch.Tensor]:
    """``random_angles(robot, batch, seed)`` -> ``(batch, n)`` angles drawn uniformly inside the limits."""

    def draw(robot: Robot, batch: int, seed: int) -> torch.Tensor:
        u = torch.rand(batch, robot.n_joints, generator=torch.Generator().manual_seed(seed), dtype=torch.float64)
        return robot.lower_limits + u.to(robot.lower_limits.dtype) * (robot.upper_limits - robot.lower_limits)

    return draw


@pytest.fixture(scope="module")
def nao() -> Robot:
    return load_robot("nao")


@pytest.fixture(scope="module")
def robots() -> dict[str, Robot]:
    """The three shipped robots by name."""
    return {name: load_robot(name) for name in ("yumi", "nao", "pepper")}


def _example_robot_data() -> Path | None:
    """The robots folder of the example-robot-data wheel (the test extra), or None."""
    from importlib import metadata

    try:
        folder = Path(metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data/robots"))
    except metadata.PackageNotFoundError:
        return None
    return folder if folder.is_dir() else None


@pytest.fixture(scope="session")
def robot_data() -> Path:
    """``robots/`` of the example-robot-data wheel: real URDFs we did not write (skip without it)."""
    folder = _example_robot_data()
    if folder is None:
        pytest.skip("example-robot-data is not installed (pip install 'nlo_lab[test]')")
    return folder
