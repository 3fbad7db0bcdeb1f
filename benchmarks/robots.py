"""Bring your own robot (issue 28): robots we did not model retarget real recordings within the targets.

    python benchmarks/robots.py [--robots yumi,nao,pepper,baxter,talos,romeo,tiago] [--train-seconds 600]
                                [--out build/robots] [--reuse] [--no-write]

For each robot: its spec (the bundled one, or drafted by ``nlo-lab robot init`` from the URDF
and SRDF of the ``example-robot-data`` wheel, the test extra), its checkpoint (the shipped one,
or trained for ``--train-seconds`` on the synthetic corpus, one torch thread, as
``nlo-lab train --robot SPEC --out CKPT --max-seconds S`` does: the best of ``TrainSettings.starts``
candidate starts by validation), then every real recording of
``../shared/data/pose`` (else the bundled sample) retargeted with the defaults. Printed per
recording, with the targets of issue 28:

* joint-limit violations (0) and velocity violations on the retimed output's time base (0);
* self-collision frames by the capsules, and by the URDF's own collision geometry minus the
  pairs the robot's SRDF disables (``nlo_lab.robot.GeometryCollision``, overlaps deeper than
  0.1 mm; 0), with the deepest overlap;
* the mean angle between the human's and the robot's shoulder -> elbow and shoulder -> wrist
  directions, against the robot standing still at its rest pose (ratio at most 0.6).

Unless ``--no-write``, the tables replace the ``robots`` section of ``docs/RESULTS.md``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_doc import stamp, update_section  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SHARED_POSE = ROOT.parent / "shared" / "data" / "pose"
TARGET_RATIO = 0.6
BUNDLED = ("yumi", "nao", "pepper")
# name -> URDF, SRDF (paths in example-robot-data's robots/), init flags
DRAFTED = {
    "baxter": ("baxter_description/urdf/baxter.urdf", "baxter_description/srdf/baxter_manipulation.srdf", {}),
    "talos": ("talos_data/robots/talos_reduced.urdf", "talos_data/srdf/talos.srdf", {}),
    "romeo": ("romeo_description/urdf/romeo.urdf", "romeo_description/srdf/romeo.srdf", {
        "left_hand": {"thumb": "LThumb3Link", "index": "LFinger13Link", "middle": "LFinger23Link", "ring": "LFinger33Link"},
        "right_hand": {"thumb": "RThumb3Link", "index": "RFinger13Link", "middle": "RFinger23Link", "ring": "RFinger33Link"}}),
    "tiago": ("tiago_description/robots/tiago_dual.urdf", None, {
        "left_hand": {"thumb": "hand_left_thumb_flex_2_link", "index": "hand_left_index_flex_3_link", "middle": "hand_left_middle_flex_3_link"},
        "right_hand": {"thumb": "hand_right_thumb_flex_2_link", "index": "hand_right_index_flex_3_link",
                       "middle": "hand_right_middle_flex_3_link"}}),
    "icub": ("icub_description/robots/icub.urdf", "icub_description/srdf/icub.srdf", {}),
    "pr2": ("pr2_description/urdf/pr2.urdf", "pr2_description/srdf/pr2.srdf", {}),
}


def robot_data() -> Path:
    from importlib import metadata

    try:
        return Path(metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data/robots"))
    except metadata.PackageNotFoundError:
        sys.exit("example-robot-data is not installed: pip install 'nlo_lab[test]'")


def recordings():
    from nlo_lab.human import load_demonstration
    from nlo_lab.paths import RECORDINGS_DIR

    paths = sorted(SHARED_POSE.glob("*.pose")) if SHARED_POSE.is_dir() else sorted(RECORDINGS_DIR.glob("*.pose"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return [(p.stem, load_demonstration(p)) for p in paths]


def prepare(name: str, out: Path, train_seconds: float, reuse: bool) -> tuple:
    """``(robot, checkpoint or None, info)``: bundled, or drafted and trained."""
    from nlo_lab.model import save_checkpoint
    from nlo_lab.robot import load_robot
    from nlo_lab.robot.spec import spec_text
    from nlo_lab.robot.spec_draft import draft_spec
    from nlo_lab.training import TrainSettings, train_model

    if name in BUNDLED:
        robot = load_robot(name)
        return robot, None, {"joints": robot.n_joints, "pairs": len(robot.spec.collision_pairs), "draft_s": 0.0, "train_s": 0.0, "steps": 0,
                             "starts": ""}
    urdf, srdf, flags = DRAFTED[name]
    data = robot_data()
    spec, ckpt = out / f"{name}.json", out / f"{name}.pt"
    t0 = time.perf_counter()
    drafted_now = not (reuse and spec.is_file())
    if drafted_now:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            draft = draft_spec(data / urdf, spec, srdf=None if srdf is None else data / srdf, **flags)
        spec.write_text(spec_text(draft.spec), encoding="utf-8")
    draft_s = time.perf_counter() - t0
    robot = load_robot(spec)
    info = {"joints": robot.n_joints, "pairs": len(robot.spec.collision_pairs), "draft_s": draft_s, "train_s": 0.0, "steps": 0, "starts": ""}
    record = out / f"{name}.info.json"  # the draft's and the training's times, kept for --reuse
    if reuse and ckpt.is_file() and record.is_file():
        kept = ("train_s", "steps", "starts") if drafted_now else ("draft_s", "train_s", "steps", "starts")  # a fresh draft's own time wins
        info.update({k: v for k, v in json.loads(record.read_text()).items() if k in kept})
    elif not (reuse and ckpt.is_file()):
        result = train_model(robot, dataclasses.replace(TrainSettings(progress=False), max_seconds=train_seconds))
        save_checkpoint(result.model, ckpt, robot)
        info.update(train_s=result.seconds, steps=result.steps, starts=starts_text(result.starts))
        record.write_text(json.dumps({k: info[k] for k in ("draft_s", "train_s", "steps", "starts")}))
    return robot, ckpt, info


def starts_text(starts: list[dict]) -> str:
    """``TrainResult.starts`` as a table cell: each start's seed and validation objective, the one that went on in bold."""
    if len(starts) < 2:
        return "1"
    best = min(range(len(starts)), key=lambda i: starts[i]["val"])
    cells = [f"{s['seed']}: {s['val']:.0f}" for s in starts]
    cells[best] = f"**{cells[best]}**"
    return f"{len(starts)} ({', '.join(cells)})"


def measure(robot, ckpt, demo) -> dict:
    from nlo_lab.evaluation.directions import direction_error
    from nlo_lab.metrics import limit_violations
    from nlo_lab.pipeline import retarget
    from nlo_lab.robot import GeometryCollision

    t0 = time.perf_counter()
    result = retarget(demo, robot, checkpoint=ckpt)
    seconds = time.perf_counter() - t0
    q = result.trajectory.angles
    geometry = GeometryCollision(robot).report(q)
    return {
        "frames": len(demo),
        "seconds": seconds,
        "limits": limit_violations(robot, q),
        "velocity": result.summary["velocity_violations"],
        "capsule_frames": result.summary["self_collision_frames"],
        "geometry_frames": geometry["frames"],
        "depth_mm": 1000 * geometry["max_depth_m"],
        "worst": geometry["worst"],
        **direction_error(robot, demo, q),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--robots", default="yumi,nao,pepper,baxter,talos,romeo,tiago")
    parser.add_argument("--train-seconds", type=float, default=600.0)
    parser.add_argument("--out", default=str(ROOT / "build" / "robots"), help="where drafted specs and checkpoints go")
    parser.add_argument("--reuse", action="store_true", help="keep specs and checkpoints already in --out (and their recorded draft and training times)")
    parser.add_argument("--no-write", action="store_true")
    args = parser.parse_args()
    import torch

    from nlo_lab.robot import check_spec

    torch.set_num_threads(1)  # as nlo-lab train and retarget do (nlo_lab.threads)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    demos = recordings()
    rows, setup, timing, met = [], [], [], True
    names = args.robots.split(",")
    drafted, bundled = [n for n in names if n not in BUNDLED], [n for n in names if n in BUNDLED]
    for name in names:
        robot, ckpt, info = prepare(name, out, args.train_seconds, args.reuse)
        report = check_spec(robot.spec.path)  # what nlo-lab robot check prints
        arm = "/".join(str(len(report.arm_joints[s])) for s in ("left", "right"))
        hand = "/".join(str(len(report.fingers[s])) for s in ("left", "right"))
        setup.append(f"| {name} | {info['joints']} | {arm} | {hand} | {info['pairs']} | {info['draft_s']:.0f} | {info['train_s']:.0f} | "
                     f"{info['steps']} | {info.get('starts', '')} |")
        print(setup[-1], flush=True)
        if name in drafted and arm == "7/7" and min(len(report.fingers[s]) for s in ("left", "right")) >= 3:
            full = "the default epochs" if info["train_s"] < 0.98 * args.train_seconds else "stopped by the time limit"
            fingers = min(len(report.fingers[s]) for s in ("left", "right"))
            starts = info.get("starts", "1").split(" ")[0]
            tried = f", the best of {starts} starts" if starts not in ("", "1") else ""
            timing.append(f"Training a robot with 7-joint arms and {fingers}-finger hands ({name}): {info['steps']} steps ({full}{tried}) in "
                          f"{info['train_s']:.0f} s on one thread of 2 loaded cores (target: 600 s): "
                          f"{'met' if info['train_s'] <= 600 else 'NOT met'}.")
        for label, demo in demos:
            m = measure(robot, ckpt, demo)
            ok = m["limits"] == 0 and m["velocity"] == 0 and m["geometry_frames"] == 0 and m["ratio"] <= TARGET_RATIO
            met &= ok
            worst = f" ({m['worst'][0]} / {m['worst'][1]})" if m["worst"] else ""
            rows.append(f"| {name} | {label} | {m['frames']} | {m['seconds']:.1f} | {m['limits']} | {m['velocity']} | {m['capsule_frames']} | "
                        f"{m['geometry_frames']} | {m['depth_mm']:.1f}{worst} | {m['mean_deg']:.1f} | {m['rest_deg']:.1f} | {m['ratio']:.2f} | "
                        f"{'yes' if ok else 'NO'} |")
            print(rows[-1], flush=True)
    body = "\n".join([
        "## Your own robot (issue 28)",
        "",
        stamp().strip(),
        "",
        *([f"Specs drafted by `nlo-lab robot init` from the URDFs (and SRDFs) of `example-robot-data`, checkpoints trained for at "
           f"most {args.train_seconds:.0f} s on one thread (train [s]: that run's wall time on the loaded machine, all starts;"
           " train steps: the chosen start's; starts: `TrainSettings.starts`, each start's best validation objective after its"
           " first steps, the lowest went on)."] if drafted else []),
        *(["The bundled robots with their shipped checkpoints."] if bundled else []),
        "Recordings: " + ", ".join(label for label, _ in demos) + " (retargeted with the defaults).",
        "",
        "| robot | actuated joints | arm joints (left/right) | fingers (left/right) | checked pairs | draft [s] | train [s] | train steps |"
        " starts (seed: validation objective) |",
        "|---|---|---|---|---|---|---|---|---|",
        *setup,
        "",
        *[line for t in timing for line in (t, "")],
        "Targets: 0 limit violations, 0 velocity violations after retiming, 0 frames where the URDF's collision geometry",
        "overlaps (deeper than 0.1 mm; the SRDF's disabled pairs left out), direction error at most 0.6 of the robot at rest.",
        "Capsule collision frames count thinned capsules' overlaps too (informative: the geometry decides).",
        "",
        "| robot | recording | frames | retarget [s] | limit viol. | velocity viol. | capsule coll. frames | geometry coll. frames |"
        " deepest [mm] | direction error [deg] | at rest [deg] | ratio | targets met |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
        *rows,
        "",
        f"All targets met: {'yes' if met else 'no'}.",
    ])
    print(f"\nall targets met: {'yes' if met else 'NO'}")
    if not args.no_write:
        update_section("robots", body)
    return 0


if __name__ == "__main__":
    sys.exit(main())
