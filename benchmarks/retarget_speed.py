"""Retargeting speed on real recordings: the two targets, where the time goes, fast against readable.

    python benchmarks/retarget_speed.py [--robot yumi] [--recording PATH ...] [--rounds 5]
        [--frames 30] [--against REV] [--no-write]

Cases, on every recording (default: the shipped ``assets/recordings/*.pose`` and, beside a
checkout, the real recordings of ``../shared/data/pose``) and on a 170-frame clip of the
synthetic test split:

1. **Whole clip**: ``RetargetConfig().build()(demo)`` with the default settings (each tree its
   own: here 40 Rprop steps and the hand stage; before this session's budget change 100 Adam steps,
   patience 5); the time is ``RetargetResult.seconds`` (targets, encoder, latent optimisation, hand
   stage), as ``benchmarks/hands.py`` measures it; the whole call (with retiming and the summary's
   metrics) in wall and CPU time too; the steps taken. Target: 170 frames to YuMi in at most 1.5 s (stretch 0.5 s).
2. **One frame**: ``Retargeter.optimize_frame`` with 30 iterations from the encoder's latent,
   inside ``single_thread()`` as the lab's panel calls it; median over ``--frames`` frames
   spread over the clip. Target: at most 50 ms (stretch 10 ms).

Variants, each in its own process and alternated round by round (the order reversed every
other round), so that all see the same machine: ``fast`` (``RetargetConfig``'s default:
the fast forms chosen by batch size), ``readable`` (``fast=False``: the paper's decoder, the
term functions, autograd through FK) and, with ``--against REV``, the package as it was at
commit REV (``git archive``; its own defaults) on today's robot descriptions and checkpoints. Medians over rounds of each process's
median; ratios from the same run. Wall time and CPU time (of the process: on a shared
machine the CPU time is the steadier one) are both reported, with the load average.

3. **Where the time goes** in one iteration (fast forms, CPU time, medians), at batch T and
   1: encoder (once per run), decoder, FK (the points the terms need), the objective's
   terms, the backward pass, the Adam step, and the rest (the loop's bookkeeping and
   Python: the measured iteration minus the stages). With ``--against REV`` also REV's.
4. **Quality**: Fréchet distance (wrist + elbow) and the final loss of every variant: the
   forms are equal, so are these (to rounding).

Writes the section ``retarget-speed:ROBOT`` of ``docs/RESULTS.md``. A benchmark prints
numbers; no test times anything.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
SHARED_POSE = ROOT.parent / "shared" / "data" / "pose"  # beside a checkout; a user's clone does not have it
NO_STOP = 10_000
SYNTHETIC = "synthetic test clips, 170 frames"


def recordings(given: list[str] | None) -> list[Path]:
    """The recordings to measure: those given, else the shipped ones and the shared ones when present."""
    if given:
        return [Path(p).resolve() for p in given]
    found = sorted((ROOT / "assets" / "recordings").glob("*.pose"))
    shared = sorted(SHARED_POSE.glob("*.pose")) if SHARED_POSE.is_dir() else []
    return found + [p for p in shared if p.name not in {f.name for f in found}]  # the shipped copy once


# ------------------------------------------------------------------ the worker (one process per variant and round)
def _demos(paths: list[str]):
    """``{name: demonstration}``: the recordings, then the synthetic 170-frame clip."""
    from speed import demo_of_length

    from nlo_lab.corpus import sign_corpus
    from nlo_lab.human import load_demonstration

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # image-only recordings warn that their depth is reconstructed
        demos = {Path(p).name: load_demonstration(p) for p in paths}
    demos[SYNTHETIC] = demo_of_length(sign_corpus("test"), 170)
    return demos


def _config(robot, model, iterations: int | None, variant: str):
    from nlo_lab.inference import OptimizeSettings
    from nlo_lab.pipeline import RetargetConfig

    # None: the tree's own defaults (budget, step rule, early stop); else that many steps, no early stop
    settings = OptimizeSettings() if iterations is None else OptimizeSettings(iterations=iterations, patience=NO_STOP)
    if variant == "readable":
        return RetargetConfig(robot, settings, model=model, fast=False)
    return RetargetConfig(robot, settings, model=model)  # fast: the default (and REV's default)


def _clock():
    return time.perf_counter(), time.process_time()


def _since(start) -> tuple[float, float]:
    wall, cpu = _clock()
    return wall - start[0], cpu - start[1]


def worker(args) -> dict:
    """Every case once for ``args.worker`` (a variant): medians of wall and CPU time, and the quality."""
    import numpy as np
    import torch

    from nlo_lab.model import load_pretrained
    from nlo_lab.robot import load_robot
    from nlo_lab.threads import single_thread

    torch.set_num_threads(1)
    robot = load_robot(args.robot)
    model = load_pretrained(robot)
    out: dict = {}
    clip = _config(robot, model, None, args.worker).build()
    one = _config(robot, model, 30, args.worker).build()
    for name, demo in _demos(args.recording).items():
        clip(demo)  # warm-up: caches (point plans, folded weights) as a running program has them
        runs = []
        for _ in range(args.repeats):
            start = _clock()
            result = clip(demo)
            runs.append((result.seconds, *_since(start)))
        inputs = one.inputs(demo)
        frames = np.linspace(0, len(demo) - 1, min(args.frames, len(demo))).astype(int)
        one.optimize_frame(inputs, int(frames[0]))
        per_frame = []
        with single_thread():  # as the lab's panel calls it
            for t in frames:
                start = _clock()
                one.optimize_frame(inputs, int(t))
                per_frame.append(_since(start))
        out[name] = {
            "frames": len(demo),
            "clip_wall": statistics.median(s for s, _, _ in runs),
            "call_wall": statistics.median(w for _, w, _ in runs),
            "clip_cpu": statistics.median(c for _, _, c in runs),
            "frame_wall": statistics.median(w for w, _ in per_frame),
            "frame_cpu": statistics.median(c for _, c in per_frame),
            "frechet_m": float(result.summary["frechet_m"]),
            "steps": int(result.optimization.iterations),
            "final_loss": float(result.summary["final_loss"]),
        }
    if args.profile:
        demo = _demos(args.recording)[args.profile]
        out["profile"] = {str(b): stage_profile(robot, model, demo, b) for b in (len(demo), 1)}
    return out


def _thread_seconds(fn) -> float:
    start = time.thread_time()
    fn()
    return time.thread_time() - start


def stage_profile(robot, model, demo, frames: int, reps: int = 30) -> dict[str, float]:
    """CPU milliseconds of one latent-optimisation iteration by stage (fast forms, batch ``frames``).

    The stages are timed one by one on the objects the optimiser builds; the whole
    iteration is measured on ``optimize_latent`` itself ((100 iterations - 0 iterations) / 100);
    "rest" is the difference (the loop's bookkeeping, Python).
    """
    import numpy as np
    import torch

    from nlo_lab.inference import Adam, OptimizeSettings, RetargetInputs, optimize_latent, smoothness_term
    from nlo_lab.objective import LossWeights, Objective
    from nlo_lab.threads import single_thread

    try:  # this tree: the forms are explicit
        from nlo_lab.inference import FastPaths

        paths = FastPaths.for_frames(frames)
        options, decode = paths.objective_options(), (lambda z: model.decode(z, paths.decoder))
        fast = {"fast": paths}
    except ImportError:  # an older tree: its process-wide defaults were the fast forms
        paths, options, decode, fast = None, {}, model.decode, {}

    def cpu_ms(fn, n: int = reps) -> float:
        """Median CPU time of ``fn()`` [ms] (this thread's: time spent waiting for a core does not count)."""
        return 1e3 * statistics.median(_thread_seconds(fn) for _ in range(n))

    x = RetargetInputs.from_demonstration(demo).index(slice(0, frames))
    out: dict[str, float] = {}
    with single_thread(), torch.no_grad():
        for p in model.parameters():
            p.requires_grad_(False)
        model.eval()
        out["encoder"] = cpu_ms(lambda: model.encode(x.encoder.node_features, x.encoder.edge_features))
        z = model.encode(x.encoder.node_features, x.encoder.edge_features)
    loss_fn = Objective(robot, x.targets, **options)
    smooth = smoothness_term(robot, x.targets, LossWeights())  # None for one frame
    numpy_step = paths is not None and paths.numpy_iteration and frames == 1
    with single_thread():
        if numpy_step:  # the whole iteration in numpy
            from nlo_lab.inference.numpy_descent import NumpyLatentLoss

            f = NumpyLatentLoss.build(model, robot, loss_fn, LossWeights().latent)
            zn = z.numpy().copy()
            q, ds = f.decoder.forward(zn)
            pts, ps = f.points.forward(q)
            terms, ts = f.terms.forward(pts)
            g_terms = np.tile(f.weights, (len(terms), 1)).astype(terms.dtype)
            out["decoder"] = cpu_ms(lambda: f.decoder.forward(zn))
            out["FK"] = cpu_ms(lambda: f.points.forward(q))
            out["terms"] = cpu_ms(lambda: f.terms.forward(pts))

            def backward():
                g_points = f.terms.backward(g_terms, ts)
                f.decoder.backward(f.points.backward(g_points, ps), ds)

            out["backward"] = cpu_ms(backward)
            adam, g = Adam(zn, 0.01), np.ones_like(zn)
        else:
            zr = z.clone().requires_grad_(True)
            q = decode(zr).to(robot.lower_limits.dtype)
            qd = q.detach().clone().requires_grad_(True)
            out["decoder"] = cpu_ms(lambda: decode(zr))
            out["FK"] = cpu_ms(lambda: loss_fn.plan.map(qd, **({"analytic_gradient": True} if paths else {})))
            def objective(q):  # the objective maps its points, then the terms; + the smoothness term
                total, _ = loss_fn(q)
                return total if smooth is None else total + smooth(q)

            out["terms"] = cpu_ms(lambda: objective(qd)) - out["FK"]

            def forward_backward():
                total = objective(decode(zr).to(robot.lower_limits.dtype))
                torch.autograd.grad(torch.add(total, zr.pow(2).flatten(1).sum(1)).sum(), zr)

            out["backward"] = cpu_ms(forward_backward) - out["decoder"] - out["FK"] - out["terms"]
            adam, g = Adam(zr.detach().clone(), 0.01), torch.ones_like(zr)
        target = zn.copy() if numpy_step else zr.detach().clone()
        out["Adam"] = cpu_ms(lambda: adam.update(target, g))
        settings = {n: OptimizeSettings(iterations=n, patience=NO_STOP, warm_start=False) for n in (0, 100)}
        whole = {n: cpu_ms(lambda s=s: optimize_latent(model, robot, x.targets, s, z0=z, **fast), 5 if n else 15) for n, s in settings.items()}
    out["iteration"] = (whole[100] - whole[0]) / 100
    out["rest"] = out["iteration"] - sum(out[k] for k in ("decoder", "FK", "terms", "backward", "Adam"))
    out["numpy iteration"] = float(numpy_step)
    return out


# ------------------------------------------------------------------ the parent: rounds, report
def _tree_of(rev: str, into: Path) -> Path:
    """The package as at commit ``rev`` (git archive) with today's assets (robot descriptions,
    checkpoints), unpacked into ``into``: the same problem, solved by that commit's code."""
    archive = into / "tree.tar"
    with open(archive, "wb") as fh:
        subprocess.run(["git", "-C", str(ROOT), "archive", rev, "nlo_lab"], stdout=fh, check=True)
    with tarfile.open(archive) as tar:
        tar.extractall(into / "tree", filter="data")
    if not (into / "tree" / "nlo_lab" / "pipeline.py").is_file():  # else the installed nlo_lab's modules fill the gaps
        raise SystemExit(f"--against {rev}: that commit has no nlo_lab/pipeline.py (it predates the house's move of the "
                         "pipeline, 7c8fe20); choose a later commit")
    (into / "tree" / "assets").symlink_to(ROOT / "assets")
    return into / "tree"


def _run(variant: str, tree: Path, args, profile: str | None) -> dict:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--robot", args.robot, "--worker", variant, "--frames", str(args.frames),
           "--repeats", str(args.repeats), *[a for p in args.recording for a in ("--recording", p)]]
    if profile:
        cmd += ["--profile", profile]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tree), str(ROOT / "benchmarks")]))
    done = subprocess.run(cmd, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"the {variant} worker failed:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def _median(runs: list[dict], name: str, key: str) -> float:
    return statistics.median(r[name][key] for r in runs)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    options = {
        "--robot": {"default": "yumi"},
        "--recording": {"action": "append", "help": "a .pose (or other) recording; repeatable (default: see above)"},
        "--rounds": {"type": int, "default": 5, "help": "processes per variant, alternated"},
        "--repeats": {"type": int, "default": 3, "help": "whole-clip runs per process"},
        "--frames": {"type": int, "default": 30, "help": "frames re-optimised per recording and process"},
        "--against": {"metavar": "REV", "help": "also the package as at this commit (e.g. the one before a change)"},
        "--no-write": {"action": "store_true"},
        "--worker": {"help": argparse.SUPPRESS},  # the worker processes
        "--profile": {"help": argparse.SUPPRESS},
    }
    for flag, kwargs in options.items():
        p.add_argument(flag, **kwargs)
    args = p.parse_args(argv)
    args.recording = [str(r) for r in recordings(args.recording)]
    if args.worker:
        print(json.dumps(worker(args)))
        return 0

    import results_doc

    load_start = os.getloadavg()
    from nlo_lab.human import load_demonstration

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lengths = {Path(r).name: len(load_demonstration(r)) for r in args.recording}
    profile_on = max(lengths, key=lambda n: lengths[n])  # the longest real recording
    with tempfile.TemporaryDirectory() as tmp:
        trees = {"fast": ROOT, "readable": ROOT}
        if args.against:
            trees[args.against] = _tree_of(args.against, Path(tmp))
        runs: dict[str, list[dict]] = {v: [] for v in trees}
        for r in range(args.rounds):
            order = list(trees) if r % 2 == 0 else list(reversed(trees))
            for variant in order:
                profile = profile_on if r == 0 and variant != "readable" else None
                runs[variant].append(_run("fast" if variant == args.against else variant, trees[variant], args, profile))
                print(f"round {r + 1}/{args.rounds} {variant}: load {os.getloadavg()[0]:.1f}", file=sys.stderr)
    load_end = os.getloadavg()
    names = [n for n in runs["fast"][0] if n != "profile"]
    variants = list(runs)
    text = report(args, runs, names, variants, profile_on, load_start, load_end, results_doc)
    print(text)
    if not args.no_write:
        print(f"wrote {results_doc.update_section(f'retarget-speed:{args.robot}', text)}")
    return 0


def report(args, runs, names, variants, profile_on, load_start, load_end, results_doc) -> str:
    busy = max(load_start[0], load_end[0]) > 1.5
    out = [f"## Retargeting speed on real recordings ({args.robot})", "", results_doc.stamp(), ""]
    out.append(
        f"Variants alternated in one run, each in its own process, {args.rounds} rounds: `fast` (the default: the fast forms"
        " chosen by batch size), `readable` (`RetargetConfig(fast=False)`: the paper's decoder, the term functions, autograd"
        " through FK)" + (f", `{args.against}` (the package as at that commit, with today's robot descriptions and"
                          " checkpoints)" if args.against else "") + ". Whole clip:"
        f" `RetargetResult.seconds` (targets, encoder, the latent optimisation and the hand stage with each variant's default"
        " settings; the figure the targets read) and"
        f" the whole call (with retiming and the summary's metrics), median of {args.repeats} per process; one frame: `Retargeter.optimize_frame`, 30 iterations, median over {args.frames} frames per process."
        " Figures are medians over the rounds; CPU = the process's CPU time (steadier than wall time on a shared machine)."
    )
    if args.against:
        out += ["", f"`{args.against}` calibrates the machine: the same recordings and robot description, solved by the code"
                " of that commit with its own objective (a different final loss means its objective had other terms, e.g."
                " before the hand terms: not the same work). Its speed against `fast` in the same run says how much of a"
                " figure is the code and how much the machine's load."]
    if busy:
        out += ["", f"**Provisional**: the machine was busy (load {load_start[0]:.1f} at the start, {load_end[0]:.1f} at the end,"
                f" {os.cpu_count()} cores); wall times are then longer than on a quiet machine, the ratios less so."]
    head = ("| recording | frames | variant | latent steps | whole clip: seconds [s] | whole call wall [s] | CPU [s] | one frame wall [ms] |"
            " CPU [ms] | Fréchet [m] | final loss |")
    out += ["", head, "|---|---|---|---|---|---|---|---|---|---|---|"]
    for name in names:
        for v in variants:
            rs = runs[v]
            out.append(
                f"| {name} | {rs[0][name]['frames']} | {v} | {rs[0][name].get('steps', '—')} | {_median(rs, name, 'clip_wall'):.3f} |"
                f" {_median(rs, name, 'call_wall'):.3f} |"
                f" {_median(rs, name, 'clip_cpu'):.3f} |"
                f" {1e3 * _median(rs, name, 'frame_wall'):.1f} | {1e3 * _median(rs, name, 'frame_cpu'):.1f} |"
                f" {rs[0][name]['frechet_m']:.4f} | {rs[0][name]['final_loss']:.2f} |"
            )
    out += ["", "Ratios (other variant / fast, same run; > 1: fast is faster):", "",
            "| recording | against | whole clip: seconds | whole call CPU | one frame wall | CPU |", "|---|---|---|---|---|---|"]
    for name in names:
        for v in variants[1:]:
            ratio = [_median(runs[v], name, k) / _median(runs["fast"], name, k) for k in ("clip_wall", "clip_cpu", "frame_wall", "frame_cpu")]
            out.append(f"| {name} | {v} | " + " | ".join(f"{x:.2f}×" for x in ratio) + " |")
    targets = [(n, runs["fast"]) for n in names if runs["fast"][0][n]["frames"] == 170]
    out += ["", "### Targets", "", "| target | measured (fast, wall) | met | stretch met |", "|---|---|---|---|"]
    for name, rs in targets:
        t = _median(rs, name, "clip_wall")
        out.append(f"| 170 frames ({name}), default settings ≤ 1.5 s (stretch 0.5 s) | {t:.3f} s | {'yes' if t <= 1.5 else '**no**'} | {'yes' if t <= 0.5 else 'no'} |")
    for name, rs in targets:
        t = 1e3 * _median(rs, name, "frame_wall")
        out.append(f"| one frame ({name}), 30 iterations ≤ 50 ms (stretch 10 ms) | {t:.1f} ms | {'yes' if t <= 50 else '**no**'} | {'yes' if t <= 10 else 'no'} |")
    profiled = [v for v in variants if "profile" in runs[v][0]]
    if profiled:
        stages = ("encoder", "decoder", "FK", "terms", "backward", "Adam", "rest", "iteration")
        out += ["", f"### Where the time goes: one iteration on {profile_on} (CPU ms, medians)", "",
                "Encoder: once per run. Decoder, FK (the points the terms need), terms: forward; backward: the whole"
                " backward pass; rest: the measured iteration (from `optimize_latent` itself) minus the stages (the loop's"
                " bookkeeping, Python, the autograd engine). At batch 1 the fast forms run the whole iteration in numpy.", "",
                "| batch | variant | " + " | ".join(stages) + " |", "|---|---|" + "---|" * len(stages)]
        for batch in runs[profiled[0]][0]["profile"]:
            for v in profiled:
                prof = runs[v][0]["profile"][batch]
                out.append(f"| {batch} | {v} | " + " | ".join(f"{prof[s]:.3f}" for s in stages) + " |")
        if len(profiled) > 1:  # this tree against REV, per iteration
            out.append("")
            for batch in runs[profiled[0]][0]["profile"]:
                now, then = (runs[v][0]["profile"][batch]["iteration"] for v in profiled)
                out.append(f"- batch {batch}: one iteration {then:.3f} ms ({profiled[1]}) -> {now:.3f} ms (fast), {then / now:.2f}×")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    sys.exit(main())
