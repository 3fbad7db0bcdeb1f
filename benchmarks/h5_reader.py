"""The price of reading ``.h5`` in a process of its own, and how long a file libhdf5 loops on takes to be refused.

    python benchmarks/h5_reader.py [--frames 100 20000 432000] [--repeats 7] [--no-write]

``nlo_lab.human.readers.h5`` hands the open file to a process of its own (``h5_extract.py``), because libhdf5
loops for ever on some corrupt files and nothing in the calling process can stop it. For files in the authors'
layout of ``--frames`` frames (one group; arms, wrist quaternions and glove points of both hands, gzip, as
the authors' data set stores them), written here: the median wall time of ``load_h5_sequences`` (the reader as it
is), of its HDF5 process alone (started, the datasets read, the arrays sent back), and of the same datasets read
with h5py in this process (what the reader did before); the price is the difference of the last two. Then the time ``load_demonstration`` takes to refuse ``tests/fuzz/corpus/h5/found-4939c48c205e.h5``
(the file ``make fuzz`` found: its CPU-time limit, ``H5_CPU_SECONDS``). Writes the section ``h5-reader`` of
docs/RESULTS.md unless ``--no-write``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import results_doc  # noqa: E402

from nlo_lab.errors import DemonstrationError  # noqa: E402
from nlo_lab.files import open_input  # noqa: E402
from nlo_lab.human import load_demonstration  # noqa: E402
from nlo_lab.human.readers import h5 as h5_reader  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
LOOPING = ROOT / "tests" / "fuzz" / "corpus" / "h5" / "found-4939c48c205e.h5"


def write_file(path: Path, frames: int) -> Path:
    """One group ``word`` of ``frames`` frames in the authors' layout, every dataset gzip-compressed."""
    rng = np.random.default_rng(0)
    t = np.arange(frames)[:, None]
    with h5py.File(path, "w") as f:
        g = f.create_group("word")
        g.attrs["fps"] = 15.0
        for s, sign in (("l", 1.0), ("r", -1.0)):
            shoulder = np.array([0.0, 0.17 * sign, 1.4]) + 0 * t
            elbow = shoulder + np.array([0.05, 0.05 * sign, -0.25]) + 0.01 * np.sin(t)
            wrist = elbow + np.array([0.25, 0.0, 0.05]) + 0 * t
            hand = wrist[:, None] + rng.normal(0.0, 0.04, (frames, 16, 3))
            data = {f"{s}_up_pos": shoulder, f"{s}_fr_pos": elbow, f"{s}_hd_pos": wrist, f"{s}_glove_pos": hand,
                    f"{s}_glove_angle": rng.normal(0.0, 20.0, (frames, 14)),
                    **{f"{s}_{p}_quat": rng.normal(size=(frames, 4)) for p in ("up", "fr", "hd")}}
            for key, value in data.items():
                g.create_dataset(key, data=value, compression="gzip")
    return path


def in_process(path: Path) -> int:
    """Every dataset of the file read with h5py in this process (the reader's reads before): the bytes read."""
    with h5py.File(path, "r") as f:
        return sum(np.asarray(d[()], dtype=np.float64).nbytes for g in f.values() for d in g.values())


def extract(path: Path) -> None:
    """The reader's HDF5 process alone (``h5._extract`` on the open file): start, reads, the arrays sent back."""
    with open_input(path, kind="HDF5", max_bytes=h5_reader.MAX_H5_BYTES, error=DemonstrationError) as handle:
        h5_reader._extract(handle, path, False)


def median_seconds(fn, repeats: int) -> float:
    fn()  # once untimed: imports, the page cache
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, nargs="+", default=[100, 20_000, 432_000])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--no-write", action="store_true", help="do not update docs/RESULTS.md")
    args = parser.parse_args(argv)
    prices = []  # (frames, the price [s])
    rows = ["| frames | file | the reader [s] | of which the HDF5 process [s] | the same reads in this process [s] | price [s] |",
            "|---:|---:|---:|---:|---:|---:|"]
    with tempfile.TemporaryDirectory(prefix="nlo_lab-h5-") as tmp:
        for frames in args.frames:
            path = write_file(Path(tmp) / f"f{frames}.h5", frames)
            repeats = args.repeats if frames <= 20_000 else max(1, args.repeats // 3)
            ours = median_seconds(lambda p=path: h5_reader.load_h5_sequences(p), repeats)
            process = median_seconds(lambda p=path: extract(p), repeats)
            before = median_seconds(lambda p=path: in_process(p), repeats)
            rows.append(f"| {frames} | {path.stat().st_size / 2**20:.1f} MiB | {ours:.3f} | {process:.3f} | {before:.3f} | "
                        f"{process - before:+.3f} |")
            prices.append((frames, process - before))
            print(rows[-1], flush=True)
            path.unlink()
    start = time.perf_counter()
    try:
        load_demonstration(LOOPING)
        refused = "read (unexpected)"
    except DemonstrationError as err:
        refused = str(err).replace(f"{ROOT}/", "")  # the repository-relative name, whatever the checkout
    looping = time.perf_counter() - start
    lines = [f"- files: the authors' layout, one group, both arms and hands, gzip; medians of {args.repeats} reads "
             f"(of {max(1, args.repeats // 3)} above 20000 frames) after one untimed read", "", *rows, "",
             "- the price of the own process: " + ", ".join(f"{p:.3f} s for a file of {n} frames" for n, p in prices),
             f"- `{LOOPING.relative_to(ROOT)}` (libhdf5 loops on it): refused after {looping:.1f} s "
             f"(`H5_CPU_SECONDS` = {h5_reader.H5_CPU_SECONDS}): {refused}"]
    text = "\n".join(lines)
    print(text)
    if not args.no_write:
        results_doc.update_section("h5-reader", "\n".join(
            ["## Reading `.h5` in a process of its own (reliability)", "", results_doc.stamp(), text, ""]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
