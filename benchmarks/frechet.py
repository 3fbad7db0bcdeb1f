"""Speed of the discrete Fréchet distance: numpy wavefront against the pure-Python loop.

Run: ``python benchmarks/frechet.py [--points 500] [--repeats 7] [--no-reference]``.
Prints the median wall time of each over several runs on random-walk curves and
the ratio, and the fast version's peak memory (tracemalloc) against the size of the
full ``n x m`` table it never builds. ``--no-reference`` skips the pure-Python loop
(for long curves: ``--points 20000 --repeats 3 --no-reference``).
A benchmark prints numbers; it is not a timed test.
"""

from __future__ import annotations

import argparse
import platform
import statistics
import time
import tracemalloc

import numpy as np

from nlo_lab.metrics import frechet_distance, frechet_distance_reference


def _median_seconds(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=500, help="points per curve")
    parser.add_argument("--repeats", type=int, default=7, help="runs per method (median reported)")
    parser.add_argument("--no-reference", action="store_true", help="time the fast version only")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    P = np.cumsum(rng.normal(scale=0.01, size=(args.points, 3)), axis=0)  # (n, 3) [m]
    Q = np.cumsum(rng.normal(scale=0.01, size=(args.points, 3)), axis=0)
    tracemalloc.start()
    fast_value = frechet_distance(P, Q)  # also warms up
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    fast = _median_seconds(lambda: frechet_distance(P, Q), args.repeats)
    print(f"machine: {platform.machine()} {platform.processor() or ''} python {platform.python_version()}, numpy {np.__version__}")
    print(f"points per curve: {args.points}, runs per method: {args.repeats} (median)")
    if not args.no_reference:
        ref_value = frechet_distance_reference(P, Q)
        assert abs(fast_value - ref_value) <= 1e-12 * max(1.0, ref_value), (fast_value, ref_value)
        ref = _median_seconds(lambda: frechet_distance_reference(P, Q), args.repeats)
        print(f"distance: {fast_value:.6f} (fast) == {ref_value:.6f} (pure Python)")
        print(f"pure-Python loop: {ref * 1e3:8.2f} ms")
    print(f"numpy wavefront:  {fast * 1e3:8.2f} ms")
    if not args.no_reference:
        print(f"speed ratio:      {ref / fast:8.1f}x")
    table = args.points * args.points * 8
    print(f"peak memory:      {peak / 1e6:8.2f} MB (the full {args.points} x {args.points} table: {table / 1e6:.1f} MB)")


if __name__ == "__main__":
    main()
