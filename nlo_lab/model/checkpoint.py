"""Checkpoints: a trained :class:`~nlo_lab.model.retarget_model.RetargetModel` on disk, and the shipped ones.

A checkpoint is a ``torch.save`` dict of plain data (loaded with
``weights_only=True``): the format version, the robot's name and joint names,
the model configuration (:func:`~nlo_lab.model.retarget_model.build_model`'s
arguments), the float32 state dict, and what training recorded. Loading
rebuilds the model from the configuration and checks that it was made for this
robot, so inference needs the model package only, never the trainer.
"""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

import torch

from nlo_lab.atomic_files import atomic_path
from nlo_lab.errors import CheckpointError, NloLabError
from nlo_lab.files import as_path, format_size, open_input
from nlo_lab.human.skeleton import skeleton_graph
from nlo_lab.model.layers import DEFAULT_ACTIVATION
from nlo_lab.model.retarget_model import RetargetModel, build_model
from nlo_lab.paths import BUNDLED_ROBOTS, CHECKPOINTS_DIR, is_bundled, is_editable_checkout, repair_hint
from nlo_lab.robot import as_robot

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot import Robot

__all__ = ["CHECKPOINT_FORMAT_VERSION", "MAX_CHECKPOINT_BYTES", "save_checkpoint", "load_checkpoint", "load_torch_file",
           "checkpoint_path", "load_pretrained"]

CHECKPOINT_FORMAT_VERSION = 2  # 2: the decoder's rest offset (decoder.rest_pre) is part of the state
MAX_CHECKPOINT_BYTES = 256 << 20  # the shipped checkpoints are 0.4-0.8 MB


def load_torch_file(path, *, kind: str = "checkpoint", max_bytes: int = MAX_CHECKPOINT_BYTES, error=CheckpointError):
    """``torch.load`` of a file written by ``torch.save``, plain data only (``weights_only=True``), memory bounded.

    The file is checked first (:func:`nlo_lab.files.open_input`: a regular file of at most
    ``max_bytes``), then its zip directory: ``torch.save`` stores every record uncompressed,
    so a compressed record (which could inflate to any size) is refused, and the records
    together must fit in the file. Pickled code never runs (``weights_only``).

    Raises:
        error: not a regular file, too large, not a zip archive of ``torch.save``, or unreadable.
    """
    with open_input(path, kind=kind, max_bytes=max_bytes, error=error) as f:
        try:
            with zipfile.ZipFile(f) as zf:
                records = zf.infolist()
        except (zipfile.BadZipFile, OSError, ValueError, EOFError, NotImplementedError):
            raise error(f"cannot be read: corrupt or not a {kind} (no zip archive, which torch.save writes)", path=path) from None
        compressed = [r.filename for r in records if r.compress_type != zipfile.ZIP_STORED]
        if compressed:
            raise error(f"cannot be read: the record {compressed[0]!r} is compressed, which torch.save never does", path=path)
        total = sum(r.file_size for r in records)
        if total > max_bytes:
            raise error(f"cannot be read: its records declare {format_size(total)}, more than the file can hold", path=path)
        f.seek(0)
        try:
            return torch.load(f, map_location="cpu", weights_only=True)
        except Exception as exc:  # torch raises many types for a damaged file
            raise error(f"cannot be read (corrupt or not a {kind}): {type(exc).__name__}", path=path) from None



def save_checkpoint(model: RetargetModel, path, robot: Robot | None = None, **info: Any) -> Path:
    """Write ``model`` (float32) with its robot name, format version and settings.

    Args:
        model: the trained model (``model.train_info`` is recorded when present).
        path: destination file (``.pt``); parent folders are created.
        robot: the robot (its joint names are recorded); optional.
        **info: extra JSON-like entries.
    """
    path = as_path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    state = {k: v.detach().to("cpu", torch.float32 if v.is_floating_point() else None) for k, v in model.state_dict().items()}
    train_info = dict(getattr(model, "train_info", {}))
    ckpt = {
        "format_version": CHECKPOINT_FORMAT_VERSION,
        "robot": model.robot_name,
        "joint_names": list(robot.joint_names) if robot is not None else None,
        "model_config": dict(model.config),
        "state_dict": state,
        "latent_mean": state["latent_mean"],
        "latent_std": state["latent_std"],
        "val_loss": train_info.get("val_loss"),
        "train_settings": train_info.get("settings"),
        "weights": train_info.get("weights"),
        "history": train_info.get("history"),
        "train_seconds": train_info.get("seconds"),
        "steps": train_info.get("steps"),
        "torch_version": str(torch.__version__),
        **info,
    }
    with atomic_path(path) as tmp:  # never a half-written checkpoint under the real name; a failure names `path`
        torch.save(ckpt, tmp)
    return path


def load_checkpoint(path, robot: Robot | str) -> RetargetModel:
    """Load a checkpoint for ``robot`` (a ``Robot`` or a name).

    Raises:
        CheckpointError: missing or corrupt file, another format version, or a
            checkpoint made for another robot (the message names both).
    """
    path = as_path(path)
    robot = as_robot(robot)
    ckpt = load_torch_file(path)
    if not isinstance(ckpt, dict) or "format_version" not in ckpt or "robot" not in ckpt:
        raise CheckpointError(f"checkpoint {path} is not an nlo_lab checkpoint (no format_version/robot)")
    if ckpt["format_version"] != CHECKPOINT_FORMAT_VERSION:
        raise CheckpointError(
            f"checkpoint {path} has format version {ckpt['format_version']!r}, this nlo_lab reads version {CHECKPOINT_FORMAT_VERSION}"
        )
    if ckpt["robot"] != robot.name:
        raise CheckpointError(f"checkpoint {path} was trained for robot {ckpt['robot']!r}, not for {robot.name!r}")
    names = ckpt.get("joint_names")
    if names is not None and (not isinstance(names, (list, tuple)) or list(names) != list(robot.joint_names)):
        raise CheckpointError(f"checkpoint {path} was made for other joints of {robot.name!r} (the robot description changed)")
    try:
        cfg = ckpt["model_config"]
        model = build_model(
            robot.name,
            robot.graph,
            robot.lower_limits,
            robot.upper_limits,
            skeleton_graph(),
            in_features=cfg["in_features"],
            edge_features=cfg["edge_features"],
            kind=cfg["kind"],
            latent_per_node=cfg["latent_per_node"],
            activation=cfg.get("activation", DEFAULT_ACTIVATION),  # checkpoints before the choice: LeakyReLU
        )
        model.load_state_dict(ckpt["state_dict"])
        if cfg.get("training") is not None:  # how it was trained (an auto-decoder has no trained encoder)
            model.config["training"] = str(cfg["training"])
    except (KeyError, RuntimeError, TypeError, NloLabError) as exc:
        raise CheckpointError(f"checkpoint {path} does not fit the model for {robot.name!r}: {exc}") from None
    model.train_info = {k: ckpt.get(k) for k in ("val_loss", "train_settings", "weights", "history", "train_seconds", "steps")}
    return model.to(dtype=robot.lower_limits.dtype).eval()


def checkpoint_path(name: str) -> Path:
    """``assets/checkpoints/{name}.pt``."""
    return CHECKPOINTS_DIR / f"{name}.pt"


def load_pretrained(robot: Robot | str, checkpoint=None) -> RetargetModel:
    """The shipped checkpoint of ``robot`` (a ``Robot`` or a name), or the file ``checkpoint``.

    Raises:
        CheckpointError: no shipped checkpoint for this robot (or a bad one); a ``checkpoint``
            that is missing, damaged or made for another robot.
    """
    robot = as_robot(robot)
    if checkpoint is not None:
        return load_checkpoint(checkpoint, robot)
    path = checkpoint_path(robot.name)
    if not path.is_file() and not (robot.name in BUNDLED_ROBOTS and is_bundled(path)):
        if is_bundled(robot.spec.path):
            raise CheckpointError(f"no trained checkpoint for robot {robot.name!r} ({path}); run `nlo-lab train --robot {robot.name}`")
        spec, out = robot.spec.path, f"{robot.name}.pt"
        raise CheckpointError(f"no trained checkpoint for robot {robot.name!r} of {spec}: train one (`nlo-lab train --robot {spec} "
                              f"--out {out}`) and give it (`--checkpoint {out}`, checkpoint= in the library)")
    try:
        return load_checkpoint(path, robot)
    except CheckpointError as exc:
        if robot.name in BUNDLED_ROBOTS and is_bundled(path) and is_bundled(robot.spec.path):  # a shipped file is missing or damaged
            retrain = f" (or retrain it: `nlo-lab train --robot {robot.name}`)" if is_editable_checkout() else ""
            raise CheckpointError(f"{exc}; {repair_hint(path)}{retrain}") from None
        raise
