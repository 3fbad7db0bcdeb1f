"""nlo_lab: kinematic motion retargeting by neural latent optimisation.

The front door, for a first retargeting::

    import nlo_lab
    result = nlo_lab.retarget(nlo_lab.load_demonstration("demo:introduction_06"), nlo_lab.load_robot("nao"))
    result.trajectory.save_csv("nao.csv")

Each name is imported from its home on first use (the module's ``__getattr__``), so that
``import nlo_lab`` stays cheap: it imports neither torch nor numpy. The homes stay the
reference: :mod:`nlo_lab.robot`, :mod:`nlo_lab.sources`, :mod:`nlo_lab.inference`, :mod:`nlo_lab.pipeline`,
:mod:`nlo_lab.human`, :mod:`nlo_lab.objective`, :mod:`nlo_lab.errors`.
"""

from __future__ import annotations

import importlib

__version__ = "0.2.0"

# name -> the module it lives in (docs/ARCHITECTURE.md, "The front door")
_HOMES = {
    "load_robot": "nlo_lab.robot",
    "Robot": "nlo_lab.robot",
    "load_demonstration": "nlo_lab.sources",  # a file, or demo:NAME
    "Demonstration": "nlo_lab.human",
    "retarget": "nlo_lab.pipeline",
    "RetargetConfig": "nlo_lab.pipeline",
    "RetargetResult": "nlo_lab.pipeline",
    "OptimizeSettings": "nlo_lab.inference",
    "LossWeights": "nlo_lab.objective",
    "RobotTrajectory": "nlo_lab.inference",
    **{name: "nlo_lab.errors" for name in (
        "NloLabError", "RobotDescriptionError", "UnknownRobotError", "DemonstrationError", "CheckpointError",
        "SettingsError", "SettingsTypeError", "OutputError", "InstallationError", "Interrupted",
    )},
}

__all__ = list(_HOMES)


def __getattr__(name: str):
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module 'nlo_lab' has no attribute {name!r}")
    value = getattr(importlib.import_module(home), name)
    globals()[name] = value  # once: later lookups do not come here
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_HOMES))
