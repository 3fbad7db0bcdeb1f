"""How long ``nlo-lab robot init`` takes on the real robots the test suite drafts (issue 28).

    python benchmarks/robot_init.py [--robots icub,baxter,talos,romeo,tiago] [--readable] [--no-write]

Each robot is drafted as ``tests/robot`` drafts it (iCub without its SRDF, as
``test_without_its_checkpoint_a_drafted_robot_says_how_to_train_one``; Baxter, Talos and Romeo with
theirs, as ``test_a_real_robot_from_urdf_to_a_retargeted_recording``; TIAGo dual with its hands, as the
``tiago_draft`` fixture), from the URDFs of the ``example-robot-data`` wheel (the test extra), one
torch thread. Printed per robot: the wall and CPU time of ``draft_spec`` (what ``nlo-lab robot init`` runs),
the capsules and checked pairs, and a digest of the drafted collision model (capsules, pairs, margins)
so that two runs (two commits, or ``--readable``) can be seen to draft the same spec.

``--readable`` drafts each robot a second time without the fast path (``prefilter=False``: a linear
programme for every sampled pose) and prints that time, their ratio and whether the two specs are
equal. Unless ``--no-write``, the table replaces the ``robot-init`` section of ``docs/RESULTS.md``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import tempfile
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_doc import stamp, update_section  # noqa: E402

HANDS = {"romeo": {f"{s}_hand": {"thumb": f"{c}Thumb3Link", "index": f"{c}Finger13Link", "middle": f"{c}Finger23Link",
                                 "ring": f"{c}Finger33Link"} for s, c in (("left", "L"), ("right", "R"))},
         "tiago": {f"{s}_hand": {"thumb": f"hand_{s}_thumb_flex_2_link", "index": f"hand_{s}_index_flex_3_link",
                                 "middle": f"hand_{s}_middle_flex_3_link"} for s in ("left", "right")}}
# name -> URDF, SRDF (paths in example-robot-data's robots/), as the tests draft them
ROBOTS = {
    "icub": ("icub_description/robots/icub.urdf", None),
    "baxter": ("baxter_description/urdf/baxter.urdf", "baxter_description/srdf/baxter_manipulation.srdf"),
    "talos": ("talos_data/robots/talos_reduced.urdf", "talos_data/srdf/talos.srdf"),
    "romeo": ("romeo_description/urdf/romeo.urdf", "romeo_description/srdf/romeo.srdf"),
    "tiago": ("tiago_description/robots/tiago_dual.urdf", None),
}


def robot_data() -> Path:
    from importlib import metadata

    try:
        return Path(metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data/robots"))
    except metadata.PackageNotFoundError:
        sys.exit("example-robot-data is not installed: pip install 'nlo_lab[test]'")


def draft(name: str, **kwargs) -> tuple[float, float, dict]:
    """``(wall seconds, CPU seconds, the drafted collision model)`` of one robot (CPU time: less swayed by a loaded machine)."""
    from nlo_lab.robot.spec_draft import draft_spec

    urdf, srdf = ROBOTS[name]
    data = robot_data()
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0, c0 = time.perf_counter(), time.process_time()
        result = draft_spec(data / urdf, Path(tmp) / f"{name}.json", srdf=None if srdf is None else data / srdf, **HANDS.get(name, {}), **kwargs)
        seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    return seconds, cpu, {k: result.spec[k] for k in ("capsules", "collision_pairs", "collision_margin")}


def digest(model: dict) -> str:
    return hashlib.sha256(json.dumps(model, sort_keys=True).encode()).hexdigest()[:12]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--robots", default=",".join(ROBOTS))
    parser.add_argument("--readable", action="store_true", help="also draft without the fast path and compare")
    parser.add_argument("--no-write", action="store_true")
    args = parser.parse_args()
    import torch

    torch.set_num_threads(1)  # as nlo-lab robot init does (nlo_lab.threads)
    import scipy.optimize  # noqa: F401  (imported lazily by the draft: not part of the first robot's time)
    import trimesh  # noqa: F401
    head = "| robot | draft [s] | CPU [s] | capsules | checked pairs | spec digest |" + (
        " readable [s] | readable CPU [s] | CPU ratio | same spec |" if args.readable else "")
    rows = [head, "|" + "---|" * head.count(" | ")]
    print(head, flush=True)
    for name in args.robots.split(","):
        seconds, cpu, model = draft(name)
        row = f"| {name} | {seconds:.1f} | {cpu:.1f} | {len(model['capsules'])} | {len(model['collision_pairs'])} | {digest(model)} |"
        if args.readable:
            slow, slow_cpu, plain = draft(name, prefilter=False)
            row += f" {slow:.1f} | {slow_cpu:.1f} | {slow_cpu / cpu:.1f} | {'yes' if plain == model else 'NO'} |"
        rows.append(row)
        print(row, flush=True)
    body = "\n".join(["## Drafting a spec (`nlo-lab robot init`, issue 28)", "", stamp().strip(), "",
                      "Robots drafted as the test suite drafts them (iCub without its SRDF; Baxter, Talos, Romeo with theirs; TIAGo "
                      "dual with its hands), one torch thread. Spec digest: of the drafted capsules, pairs and margins.", "", *rows])
    if not args.no_write:
        update_section("robot-init", body)
    return 0


if __name__ == "__main__":
    sys.exit(main())
