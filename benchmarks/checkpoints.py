"""The shipped checkpoints as their training recorded them: steps, epochs, training time, best validation loss, size.

Reads ``assets/checkpoints/*.pt`` (nothing is trained: the numbers are those of the run that made
each file, ``assets/checkpoints/README.md`` has its command) and writes the section ``checkpoints``
of ``docs/RESULTS.md``. Run: ``.venv/bin/python benchmarks/checkpoints.py [--no-write]``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import results_doc  # noqa: E402

from nlo_lab.model import checkpoint_path, load_pretrained  # noqa: E402
from nlo_lab.paths import BUNDLED_ROBOTS  # noqa: E402


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--no-write", action="store_true", help="print only; leave the results file alone")
    args = p.parse_args(argv)
    rows = ["| robot | steps | epochs | batch | lr | training time (wall) [s] | best validation loss | activation | size [MB] |",
            "|---|---|---|---|---|---|---|---|---|"]
    for name in BUNDLED_ROBOTS:
        model = load_pretrained(name)
        info, settings = model.train_info, model.train_info.get("train_settings") or {}
        rows.append(
            f"| {name} | {info['steps']} | {settings.get('epochs', '?')} | {settings.get('batch_size', '?')} | {settings.get('lr', '?')} |"
            f" {info['train_seconds']:.0f} | {info['val_loss']:.1f} | {model.config.get('activation', 'leaky_relu')} |"
            f" {checkpoint_path(name).stat().st_size / 1e6:.2f} |"
        )
    body = "\n".join([
        "## The shipped checkpoints", "", results_doc.stamp(),
        "As their training recorded them (`train_info` of each `assets/checkpoints/NAME.pt`; nothing is trained here): the"
        " training time is that run's wall time on its machine (`assets/checkpoints/README.md`: the command, the machine,"
        " three runs in parallel on 2 cores).", "", *rows, "",
    ])
    results_doc.publish({"checkpoints": body}, not args.no_write)
    return 0


if __name__ == "__main__":
    sys.exit(main())
