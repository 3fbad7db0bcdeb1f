"""How the conditioning parameters of ``nlo_lab.human.conditioning`` were chosen (prints tables).

    python benchmarks/conditioning.py [--clips N] [--seed S]

1. Noise of the real recordings (``../shared/data/pose/``, skipped when absent): per arm
   point, the RMS of the second difference ``x[t+1] - 2 x[t] + x[t-1]`` of the raw
   landmarks (read with ``condition=False``). For white noise of σ per coordinate this is
   ``sqrt(6) σ`` per coordinate; a smooth motion adds little at 25 fps.
2. Synthetic test clips (known truth) with that noise added to every arm point, plus
   outlier frames (2 % of the frames, a point moved 0.2-0.5 m): RMS error against the
   truth after conditioning, for Savitzky-Golay windows of 0.12-0.44 s and orders 2 and 3,
   with and without the outlier repair. The chosen window and order are the lowest error.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

from nlo_lab.corpus import sign_corpus
from nlo_lab.human import Demonstration
from nlo_lab.human import conditioning as cond

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "pose"


def real_noise() -> float | None:
    """Median over the real recordings' arm points of the per-coordinate noise σ [m] (from second differences)."""
    from nlo_lab.human.readers.pose import load_pose

    if not SHARED.is_dir():
        print(f"note: {SHARED} is absent: noise level assumed 0.01 m", file=sys.stderr)
        return None
    sigmas = []
    for path in sorted(SHARED.glob("*.pose")):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            d = load_pose(path, condition=False)
        for s in range(2):
            for j in (1, 2):
                p, m = d.arm_positions[:, s, j], d.arm_mask[:, s, j]
                ok = m[2:] & m[1:-1] & m[:-2]
                dd = (p[2:] - 2 * p[1:-1] + p[:-2])[ok]
                if len(dd) > 5:
                    sigma = float(np.sqrt(np.median(dd**2))) / np.sqrt(6)
                    sigmas.append(sigma)
                    print(f"{path.stem:28s} {('left', 'right')[s]:5s} {('shoulder', 'elbow', 'wrist')[j]:6s} σ ≈ {sigma * 1000:5.1f} mm")
    return float(np.median(sigmas)) if sigmas else None


def noisy(demo: Demonstration, sigma: float, outliers: float, rng) -> Demonstration:
    arms = demo.arm_positions + rng.normal(0.0, sigma, demo.arm_positions.shape)
    T = len(demo)
    for _ in range(int(round(outliers * T * 6))):  # 6 arm points
        t, s, j = rng.integers(0, T), rng.integers(0, 2), rng.integers(0, 3)
        direction = rng.normal(size=3)
        arms[t, s, j] += direction / np.linalg.norm(direction) * rng.uniform(0.2, 0.5)
    return Demonstration(demo.fps, arms, demo.arm_mask, demo.wrist_rotations, demo.wrist_mask, demo.finger_positions,
                         demo.finger_mask, name=demo.name)


def error(clean: Demonstration, d: Demonstration) -> float:
    e = np.linalg.norm(d.arm_positions - clean.arm_positions, axis=-1)[:, :, 1:]  # elbows and wrists
    return float(np.sqrt(np.nanmean(e**2)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clips", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    sigma = real_noise() or 0.01
    print(f"\nnoise σ used: {sigma * 1000:.1f} mm per coordinate, outliers 2 % of the point-frames\n")
    clips = sign_corpus("test")[: args.clips]
    rng = np.random.default_rng(args.seed)
    pairs = [(c, noisy(c, sigma, 0.02, rng)) for c in clips]
    raw = np.mean([error(c, n) for c, n in pairs])
    print(f"raw (no conditioning): RMS error {raw * 1000:.1f} mm")
    print("\n| window [s] | order | RMS error, repair + smoothing [mm] | smoothing only [mm] |\n|---|---|---|---|")
    default = (cond.SMOOTH_SECONDS, cond.SMOOTH_ORDER)
    best = None
    for seconds in (0.12, 0.2, 0.28, 0.36, 0.44):
        for order in (2, 3):
            saved = cond.SMOOTH_SECONDS, cond.SMOOTH_ORDER
            cond.SMOOTH_SECONDS, cond.SMOOTH_ORDER = seconds, order
            try:
                full = np.mean([error(c, cond.condition_demonstration(n)) for c, n in pairs])
                only = []
                for c, n in pairs:
                    w = cond.window_frames(n.fps, seconds, order)
                    arms = n.arm_positions.copy()
                    for s in range(2):
                        for j in range(3):
                            arms[:, s, j] = cond.savgol(arms[:, s, j], n.arm_mask[:, s, j], w, order)
                    only.append(error(c, Demonstration(n.fps, arms, n.arm_mask, n.wrist_rotations, n.wrist_mask,
                                                       n.finger_positions, n.finger_mask)))
            finally:
                cond.SMOOTH_SECONDS, cond.SMOOTH_ORDER = saved
            mark = " (default)" if (seconds, order) == default else ""
            print(f"| {seconds:.2f}{mark} | {order} | {full * 1000:.1f} | {np.mean(only) * 1000:.1f} |")
            if best is None or full < best[0]:
                best = (full, seconds, order)
    print(f"\nlowest error: window {best[1]:.2f} s, order {best[2]} ({best[0] * 1000:.1f} mm; raw {raw * 1000:.1f} mm)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
