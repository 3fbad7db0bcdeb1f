"""What decides a batch's outputs, as plain values: the robot, the optimisation flags, the weights.

:class:`BatchSettings` travels to the workers (it pickles small) and names the settings in
``summary.json`` and ``results.csv`` by a fingerprint (:meth:`BatchSettings.fingerprint`): an
input done before with the same content and the same fingerprint is skipped. The fingerprint
covers nlo_lab's version and the robot's files (spec, URDF, checkpoint: a retrained model
changes it) and is computed without torch, so a resumed run over a finished corpus needs
neither torch nor a cluster. Settings are compared as given: ``--weights ee=1000`` (the
default value) counts as a different setting from no ``--weights``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import nlo_lab
from nlo_lab.batch.inputs import file_sha256
from nlo_lab.paths import CHECKPOINTS_DIR, ROBOTS_DIR
from nlo_lab.settings import LATENT_ITERATIONS, SLOWDOWN_RANGE, check_range

__all__ = ["BatchSettings", "robot_files"]


def robot_files(robot: str) -> list[Path]:
    """The files a robot's retargeting reads: its spec, the URDF the spec names, its checkpoint.

    Resolved as :func:`nlo_lab.robot.load_robot` does (a bundled name wins over a same-named
    file), without importing torch; a file that cannot be found or read is left out (the
    robot's loading names it properly when the batch starts).
    """
    spec = ROBOTS_DIR / f"{robot}.json"
    if not spec.is_file():
        spec = Path(robot)
    if not spec.is_file():
        return []
    files = [spec]
    try:
        data = json.loads(spec.read_text(encoding="utf-8"))
        files += [spec.parent / str(data["urdf"]), CHECKPOINTS_DIR / f"{data['name']}.pt"]
    except (OSError, ValueError, KeyError, TypeError, RecursionError):
        return files
    return [f for f in files if f.is_file()]


def _canonical_weights(weights) -> tuple[tuple[str, float], ...] | str:
    """Weights as given, in a canonical (hashable) form: ``((name, value), ...)`` sorted by name;
    a text that does not parse stays text (building the retargeter then names what is wrong)."""
    if weights is None:
        return ()
    if dataclasses.is_dataclass(weights):  # a LossWeights: the fields that differ from their defaults
        return tuple((f.name, float(getattr(weights, f.name))) for f in dataclasses.fields(weights)
                     if getattr(weights, f.name) != f.default)
    try:
        if isinstance(weights, str):
            weights = dict(item.split("=") for item in weights.split(",") if item.strip())
        return tuple(sorted((str(k).strip(), float(v)) for k, v in dict(weights).items()))
    except (ValueError, TypeError):
        return str(weights).strip()


@dataclass(frozen=True)
class BatchSettings:
    """The settings of a batch (the flags of ``nlo-lab batch``), as plain values.

    Attributes:
        robot: a bundled robot's name or a robot spec ``.json`` path.
        init: initialisation of the latent code (:data:`nlo_lab.inference.INITS`).
        iterations: the latent optimisation's budget.
        seed: seed of the random initialisations.
        weights: loss weights: ``"ee=1000,ori=100"``, a mapping, a
            :class:`~nlo_lab.objective.LossWeights` or None (the defaults); kept in a
            canonical form: the pairs given, sorted by name.
        viewer: also write ``viewer.html`` for each input.
        hand_search: fingers whose joints the hand stage first searches (``--hand-search``,
            :attr:`OptimizeSettings.hand_search <nlo_lab.inference.OptimizeSettings.hand_search>`); None (the
            default): the robot's default fingers, ``()``: no search; in the fingerprint only when given, so that the
            fingerprints of batches without it stay as they were.
        hand_slowdown: how much longer than the latent optimisation's the hand stage may make each retimed segment
            (``--hand-slowdown``, :attr:`OptimizeSettings.hand_slowdown
            <nlo_lab.inference.OptimizeSettings.hand_slowdown>`); in the fingerprint only when not 1, likewise.
    """

    robot: str
    init: str = "encoder"
    iterations: int = LATENT_ITERATIONS
    seed: int = 0
    weights: Any = ()
    viewer: bool = False
    hand_search: tuple[str, ...] | None = None
    hand_slowdown: float = 1.0

    def __post_init__(self) -> None:
        robot = getattr(getattr(self.robot, "spec", None), "path", self.robot)  # a loaded Robot: its spec file
        object.__setattr__(self, "robot", str(robot))
        object.__setattr__(self, "weights", _canonical_weights(self.weights))
        search = self.hand_search
        object.__setattr__(self, "hand_search", None if search is None else (search,) if isinstance(search, str) else tuple(search))
        # refused here, in the client, before any input is read (the workers' OptimizeSettings checks it again)
        object.__setattr__(self, "hand_slowdown", check_range("hand_slowdown", self.hand_slowdown, *SLOWDOWN_RANGE))

    def key(self) -> dict:
        """What the fingerprint is made of: the robot by its files' contents (a name and a path to the
        same spec are one robot); not ``viewer`` (it adds a file, it changes no result)."""
        digest = hashlib.sha256()
        for f in robot_files(self.robot):
            digest.update(f.name.encode() + b"\0" + file_sha256(f).encode())
        key = {"nlo_lab": nlo_lab.__version__, "robot_files": digest.hexdigest(),
               "init": self.init, "iterations": self.iterations, "seed": self.seed, "weights": self.weights}
        if self.hand_search is not None:
            key["hand_search"] = list(self.hand_search)
        if self.hand_slowdown != 1.0:
            key["hand_slowdown"] = float(self.hand_slowdown)
        return key

    def fingerprint(self) -> str:
        """A short hash of :meth:`key` (hex): equal for equal settings and robot files."""
        text = json.dumps(self.key(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def build(self):
        """The retargeter these settings describe (imports torch; loads the robot and its model).

        Raises:
            NloLabError: an unknown robot, a bad spec or checkpoint, a setting out of range.
        """
        # lazy: torch: building the retargeter is the workers' work, not the client's
        from nlo_lab.inference import OptimizeSettings
        from nlo_lab.objective import LossWeights
        from nlo_lab.pipeline import RetargetConfig
        from nlo_lab.robot import load_robot

        settings = OptimizeSettings(init=self.init, iterations=self.iterations, seed=self.seed, hand_search=self.hand_search,
                                    hand_slowdown=self.hand_slowdown)
        text = self.weights if isinstance(self.weights, str) else ",".join(f"{k}={v!r}" for k, v in self.weights)
        weights = LossWeights.from_string(text)  # its errors name an unknown or bad weight
        return RetargetConfig(load_robot(self.robot), settings, weights).build()
