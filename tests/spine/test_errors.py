"""The library's contract (issue 25): NloLabError subclasses that are also the matching built-ins, bounded settings.

Every exception class nlo_lab defines on NloLabError also derives from a built-in exception
(ValueError, TypeError, OSError, LookupError, ImportError), so code written with ``except
ValueError`` keeps working; nothing raises the bare base class. Settings refuse the wrong type
(``LossWeights(ee="5")``) and budgets beyond their stated ranges (``iterations=10**9``).
"""

from __future__ import annotations

import ast
import errno
import importlib
import inspect
import pkgutil
from pathlib import Path

import numpy as np
import pytest

import nlo_lab
from nlo_lab.errors import DemonstrationError, NloLabError, SettingsError, SettingsTypeError

PACKAGE = Path(nlo_lab.__file__).resolve().parent
BUILTINS = (ValueError, TypeError, OSError, LookupError, ImportError)


def _modules():
    for info in pkgutil.walk_packages([str(PACKAGE)], prefix="nlo_lab."):
        if info.name.startswith("nlo_lab.cli"):  # imports the command line's parser only; its errors are checked there
            continue
        yield info.name


def test_every_error_class_is_also_a_builtin():
    found = {}
    for name in _modules():
        try:
            module = importlib.import_module(name)
        except ImportError:  # an optional extra (video, lab) not installed
            continue
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if issubclass(cls, NloLabError) and cls is not NloLabError and cls.__module__.startswith("nlo_lab"):
                found[f"{cls.__module__}.{cls.__qualname__}"] = cls
    assert len(found) >= 10
    lacking = sorted(name for name, cls in found.items() if not issubclass(cls, BUILTINS))
    assert not lacking, f"NloLabError subclasses without a built-in base: {lacking}"


def test_nothing_raises_the_bare_base_class():
    """``raise NloLabError(...)`` would be caught by no ``except ValueError``: each raise names its subclass."""
    bare = []
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Raise) and isinstance(node.exc, ast.Call) and getattr(node.exc.func, "id", None) == "NloLabError":
                bare.append(f"{path.relative_to(PACKAGE)}:{node.lineno}")
    assert not bare, bare


@pytest.mark.parametrize("field", ["ee", "ori", "elbow", "finger", "collision", "latent", "smooth"])
@pytest.mark.parametrize("value, error, match", [
    ("5", SettingsTypeError, "must be a number, got '5'"),
    (None, SettingsTypeError, "must be a number, got None"),
    (True, SettingsTypeError, "must be a number, got True"),
    ([1.0], SettingsTypeError, "must be a number"),
    (1e39, SettingsError, r"must be in \[0, 1e\+06\], got 1e\+39"),
    (-1.0, SettingsError, r"must be in \[0, 1e\+06\]"),
    (float("nan"), SettingsError, "must be in"),
])
def test_loss_weights_refuse_text_and_out_of_range(field, value, error, match):
    from nlo_lab.objective import LossWeights

    with pytest.raises(error, match=f"loss weight {field} {match}"):
        LossWeights(**{field: value})
    assert LossWeights(**{field: np.float32(2.0)}).as_dict()[field] == 2.0  # numpy scalars are numbers


def test_a_type_error_is_both_classes():
    from nlo_lab.objective import LossWeights

    with pytest.raises(TypeError):
        LossWeights(ee="5")
    with pytest.raises(ValueError):
        LossWeights(ee="5")  # a SettingsError is a ValueError too


@pytest.mark.parametrize("make", [
    "OptimizeSettings(iterations=10**9)",
    "OptimizeSettings(patience=10**9)",
    "OptimizeSettings(seed=2**40)",
    "OptimizeSettings(lr=1e9)",
    "OptimizeSettings(warm_start='yes')",
    "JointOptimizeSettings(iterations=10**9)",
    "TrainSettings(epochs=10**9)",
    "TrainSettings(batch_size=10**12)",
    "TrainSettings(latent_per_node=10**6)",
    "TrainSettings(max_seconds=1e300)",
    "SupervisedSettings(label_iterations=10**9)",
    "SupervisedSettings(hidden=(10**9,))",
    "BaselineSettings(iterations=10**9)",
    "BaselineSettings(ik_iterations=10**9)",
])
def test_budgets_and_sizes_have_upper_bounds(make):
    from nlo_lab.evaluation import BaselineSettings  # noqa: F401
    from nlo_lab.inference import JointOptimizeSettings, OptimizeSettings  # noqa: F401
    from nlo_lab.training import SupervisedSettings, TrainSettings  # noqa: F401

    with pytest.raises(SettingsError):
        eval(make)


def test_the_command_line_and_the_settings_share_the_ranges():
    from nlo_lab import settings

    assert settings.ITERATIONS_RANGE == (0, 10_000) and settings.WEIGHT_RANGE == (0.0, 1e6)
    assert settings.EPOCHS_RANGE == (1, 10_000) and settings.SEED_RANGE == (0, 2**32 - 1)


def test_retarget_config_checks_its_arguments(nao):
    from nlo_lab.inference import OptimizeSettings
    from nlo_lab.pipeline import RetargetConfig

    for kwargs, match in (({"robot": "nao"}, "robot must be a Robot"), ({"settings": {"iterations": 5}}, "settings must be OptimizeSettings"),
                          ({"weights": "ee=1"}, "weights must be LossWeights"), ({"chunk_frames": 0}, "chunk_frames"),
                          ({"chunk_frames": 10**9}, "chunk_frames"), ({"retime": "no"}, "retime must be True or False")):
        args = {"robot": nao, **kwargs}
        with pytest.raises(SettingsError, match=match):
            RetargetConfig(**args).build()
    retargeter = RetargetConfig(nao, OptimizeSettings(iterations=0)).build()
    with pytest.raises(SettingsTypeError, match="demo must be a Demonstration"):
        retargeter(np.zeros((3, 2, 3, 3)))


# ----------------------------------------------------------------------------- no silent wrong success
def _demo(**change):
    from nlo_lab.corpus import corpus_clip

    d = corpus_clip("introduction_06")
    for name, fn in change.items():
        fn(getattr(d, name))
    return d


def test_coordinates_beyond_a_kilometre_are_an_error(tmp_path):
    """The issue's case: coordinates of 3e38 were retargeted with exit 0."""
    from nlo_lab.human import Demonstration, load_demonstration, save_npz

    d = _demo()
    arms = d.arm_positions.copy()
    arms[5, 1, 2] = [3e38, 0.0, 0.0]
    with pytest.raises(DemonstrationError, match=r"arm_positions holds a coordinate of 3e\+38 m, beyond the 1000 m"):
        Demonstration(d.fps, arms, d.arm_mask, d.wrist_rotations, d.wrist_mask, d.finger_positions, d.finger_mask)
    fingers = d.finger_positions.copy()
    fingers[3, 0, 1, 1] = [0.0, -1500.0, 0.0]
    with pytest.raises(DemonstrationError, match=r"finger_positions holds a coordinate of -1.5e\+03 m") as err:
        Demonstration(d.fps, d.arm_positions, d.arm_mask, d.wrist_rotations, d.wrist_mask, fingers, d.finger_mask)
    assert err.value.frame == 3
    path = save_npz(d, tmp_path / "ok.npz")
    d.arm_positions[7, 0, 0, 2] = -2000.0  # changed after construction: the reader and retarget() check again
    import zipfile

    with zipfile.ZipFile(path) as z:
        members = {n: z.read(n) for n in z.namelist()}
    import io

    buf = io.BytesIO()
    np.save(buf, d.arm_positions)
    members["arm_positions.npy"] = buf.getvalue()
    with zipfile.ZipFile(path, "w") as z:
        for n, data in members.items():
            z.writestr(n, data)
    with pytest.raises(DemonstrationError, match=r"beyond the 1000 m .*\(file .*ok.npz, frame 7, field arm_positions\)"):
        load_demonstration(path)


def test_a_demonstration_read_from_a_file_names_it_in_later_errors(tmp_path, nao):
    from nlo_lab.human import load_demonstration, save_npz
    from nlo_lab.pipeline import retarget

    path = save_npz(_demo(), tmp_path / "clip.npz")
    demo = load_demonstration(path)
    assert demo.path == str(path)
    demo.arm_positions[2, 0, 1] = np.nan  # broken after reading
    with pytest.raises(DemonstrationError, match=r"NaN or inf .*\(file .*clip.npz, frame 2, field arm_positions\)"):
        retarget(demo, nao)


def test_a_nan_loss_names_the_file(tmp_path, nao, nan_loss):
    from nlo_lab.human import load_demonstration, save_npz
    from nlo_lab.inference import OptimizeSettings
    from nlo_lab.pipeline import retarget

    demo = load_demonstration(save_npz(_demo(), tmp_path / "clip.npz"))
    with pytest.raises(SettingsError, match=r"the loss became NaN or infinite retargeting 'introduction_06' to nao .*\(file .*clip.npz\)"):
        retarget(demo, nao, settings=OptimizeSettings(iterations=1))


def test_a_full_disk_names_the_users_file_not_a_temporary_one(tmp_path, monkeypatch):
    from nlo_lab import atomic_files

    target = tmp_path / "landmarks.pose"

    def full(path, payload):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(Path, "write_bytes", full)
    with pytest.raises(OSError) as err:
        atomic_files.atomic_write_bytes(target, b"x" * 10)
    assert err.value.errno == errno.ENOSPC and err.value.filename == str(target)
    assert list(tmp_path.iterdir()) == []
