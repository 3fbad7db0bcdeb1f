"""Run dex-retargeting (vector retargeting) on hand landmarks from a file; write the joint angles back.

This runs in the benchmark's own environment (``make bench-venv``: ``.venv-bench``, numpy >= 2 and
dex-retargeting 0.5, which cannot share an environment with mediapipe), started by
``benchmarks/hands.py`` as a subprocess::

    .venv-bench/bin/python benchmarks/hands/dex_runner.py IN.npz OUT.npz [PASSES]

It imports numpy, yaml and dex_retargeting only. IN.npz holds, for N hand-frames in order:
``points (N, 21, 3)`` MediaPipe hand landmarks in the robot's wrist-link frame [m] (the ones the
configs name are filled, the others NaN), ``side (N,)`` 0 left / 1 right, ``segment (N,)`` the
hand's run (one hand of one recording: dex-retargeting warm-starts each frame from the last and
filters along a run; it is reset between runs), ``scaling (N,)`` the config's scaling factor.
OUT.npz holds, per variant (``filtered``: the configs' low-pass filter, ``unfiltered``: alpha -1),
``q_VARIANT (N, 6)`` the actuated joints in the configs' ``target_joint_names`` order [rad] and
``seconds_VARIANT (N,)`` the wall time of each ``retarget`` call [s]; ``joint_names_left/right``.
The variants run PASSES times (default 1) over all hand-frames, one after the other: ``q`` is the first pass's
(the same in every pass: each run starts from a new retargeter), ``seconds`` the median pass's (by its total) and
``pass_seconds_VARIANT (PASSES,)`` every pass's total [s]; a timing that a busy moment of a shared machine
lengthens then counts once.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import yaml

HERE = Path(__file__).resolve().parent
CONFIGS = {0: HERE / "inspire_left.yml", 1: HERE / "inspire_right.yml"}
VARIANTS = {"filtered": None, "unfiltered": -1.0}  # None: the config's low_pass_alpha


def _config(side: int) -> dict:
    cfg = yaml.safe_load(CONFIGS[side].read_text())["retargeting"]
    cfg["urdf_path"] = str(HERE / cfg["urdf_path"])
    return cfg


def run(points: np.ndarray, side: np.ndarray, segment: np.ndarray, scaling: np.ndarray, alpha) -> tuple[np.ndarray, np.ndarray, dict]:
    from dex_retargeting.retargeting_config import RetargetingConfig

    q, seconds, names = np.full((len(points), 6), np.nan), np.zeros(len(points)), {}
    for seg in np.unique(segment):
        rows = np.flatnonzero(segment == seg)
        s = int(side[rows[0]])
        cfg = _config(s)
        override = {"scaling_factor": float(scaling[rows[0]])}
        if alpha is not None:
            override["low_pass_alpha"] = alpha
        retargeting = RetargetingConfig.from_dict(cfg, override).build()
        indices = np.asarray(cfg["target_link_human_indices"])
        dof_names = list(retargeting.joint_names)
        pick = [dof_names.index(n) for n in cfg["target_joint_names"]]
        names[s] = cfg["target_joint_names"]
        for i in rows:
            ref = points[i, indices[1]] - points[i, indices[0]]
            start = time.perf_counter()
            qpos = retargeting.retarget(ref)
            seconds[i] = time.perf_counter() - start
            q[i] = qpos[pick]
    return q, seconds, names


def main(argv: list[str]) -> int:
    if len(argv) not in (2, 3) or (len(argv) == 3 and not (argv[2].isdigit() and int(argv[2]) > 0)):
        print("usage: dex_runner.py IN.npz OUT.npz [PASSES]", file=sys.stderr)
        return 2
    passes = int(argv[2]) if len(argv) == 3 else 1
    with np.load(argv[0]) as f:
        points, side, segment, scaling = (f[k] for k in ("points", "side", "segment", "scaling"))
    out, names = {}, {}
    for variant, alpha in VARIANTS.items():
        runs = [run(points, side, segment, scaling, alpha) for _ in range(passes)]
        totals = np.array([seconds.sum() for _, seconds, _ in runs])
        median = int(np.argsort(totals)[(passes - 1) // 2])  # the median pass (the lower of the two middle ones)
        q, _, names = runs[0]
        out[f"q_{variant}"], out[f"seconds_{variant}"], out[f"pass_seconds_{variant}"] = q, runs[median][1], totals
    for s, key in ((0, "joint_names_left"), (1, "joint_names_right")):
        out[key] = np.array(names.get(s, []), dtype=str)
    tmp = Path(argv[1]).with_suffix(".tmp.npz")
    np.savez(tmp, **out)
    tmp.replace(argv[1])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
