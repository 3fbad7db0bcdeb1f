"""Quality benchmark: the paper's Table I (in two modes), Table III and initialisation ablation on our data.

Run (full, about 30-50 min on 2 cores for YuMi)::

    .venv/bin/python benchmarks/quality.py --robot yumi

Quick check (a few minutes)::

    .venv/bin/python benchmarks/quality.py --robot yumi --quick

Parts (each method's wall time measured in the same run):

1. **Table I**, once per mode (``--modes``; :data:`nlo_lab.evaluation.EVALUATION_MODES`):
   *paper* (the paper's objective: no smoothness term, frames independent, no
   retiming) and *robot-ready* (the shipped defaults: smoothness term, warm start,
   retimed output). Every method of ``nlo_lab.evaluation`` on the test split: Fréchet
   distance per sequence (``*`` = self-collision in the sequence), mean,
   velocity/acceleration error, limit and velocity violations, wall time.
2. **Initialisation ablation** (first ``--ablation-limit`` test sequences, the paper's
   objective): encoder, random ``N(0, 0.1)`` and ``N(0, 0.2)`` (the paper's variances 0.1
   and 0.2, i.e. σ = 0.32 and 0.45), train-stats; mean loss against iteration (plot) and
   Fréchet distance at budgets 0/10/25/50/100 (each budget a separate run with
   ``iterations=b`` and no early stop); joint-space optimisation at the same budgets for
   reference.
3. **Table III**: graph vs MLP encoder/decoder, FK objective vs supervised on
   joint-space optimisation labels, each 'Init' (encoder output) and 'Optim'
   (+ latent optimisation, the paper's objective). All four variants are trained in this
   run on the same training frames (every 4th frame of the train split) for the same
   number of optimiser steps (``--train-steps``, batch 64), validated on other train frames.

Writes the sections ``table1:ROBOT:MODE``, ``init:ROBOT`` and ``table3:ROBOT`` of
``docs/RESULTS.md`` and PNG plots under ``docs/figures/``. A benchmark prints numbers; it
is not a timed test.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
import results_doc  # noqa: E402

from nlo_lab.corpus import sign_corpus  # noqa: E402
from nlo_lab.errors import CheckpointError  # noqa: E402
from nlo_lab.evaluation import EVALUATION_MODES, BaselineSettings, evaluate, format_table  # noqa: E402
from nlo_lab.inference import (  # noqa: E402
    PAPER_ITERATIONS,
    JointOptimizeSettings,
    OptimizeSettings,
    RetargetInputs,
    optimize_joints,
    optimize_latent,
)
from nlo_lab.metrics import self_collision_frames, tracking_errors  # noqa: E402
from nlo_lab.model import load_pretrained  # noqa: E402
from nlo_lab.objective import LossWeights  # noqa: E402
from nlo_lab.robot import load_robot  # noqa: E402
from nlo_lab.training import (  # noqa: E402
    SupervisedSettings,
    TrainSettings,
    corpus_inputs,
    supervised_dataset,
    supervised_network,
    train_model,
    train_variant,
)

BUDGETS = (0, 10, 25, 50, 100)
INITS = {  # label -> OptimizeSettings overrides; the paper's Gaussians have variance 0.1 and 0.2 (σ = √variance)
    "encoder": dict(init="encoder"),
    "random N(0, 0.1), σ=0.32": dict(init="random", latent_sigma=0.1**0.5),
    "random N(0, 0.2), σ=0.45": dict(init="random", latent_sigma=0.2**0.5),
    "train-stats": dict(init="train-stats"),
}
NO_STOP = 10_000  # patience: every budget runs its full number of steps
PAPER = LossWeights.paper()  # the ablations use the paper's objective: frames independent, no hand terms of ours


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _model(robot, train_seconds: float, log: list[str]):
    """The shipped checkpoint, or (when there is none) a model trained here for ``train_seconds``, said so in the report."""
    try:
        model = load_pretrained(robot)
        info = getattr(model, "train_info", {}) or {}
        secs = info.get("train_seconds")
        log.append(
            f"model: shipped checkpoint `assets/checkpoints/{robot.name}.pt`"
            + (f" (trained {secs:.0f} s, {info.get('steps')} steps)" if secs else "")
        )
        return model
    except CheckpointError as exc:
        print(f"note: {exc}; training a model for {train_seconds:.0f} s instead", file=sys.stderr)
        r = train_model(robot, TrainSettings(max_seconds=train_seconds, epochs=1000, progress=True))
        log.append(f"model: **no shipped checkpoint**; trained in this run for {r.seconds:.0f} s ({r.steps} steps), default TrainSettings")
        return r.model


# ---------------------------------------------------------------------- Table I
def table1(robot, demos, settings, model, network):
    """Every method on ``demos`` in ``settings.mode``; the similarity-against-time plot."""
    ev = evaluate(robot, demos, settings, model=model, network=network, progress=True)
    print(format_table(ev))
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 3.8))
    for m in ev.methods:
        x, y = ev.total(m, "seconds") / max(1, len(ev.sequences)), ev.mean(m)
        ax.scatter(x, y, s=40, marker="*" if ev.collision_sequences(m) else "o")
        ax.annotate(m + ("†" if ev.collision_sequences(m) else ""), (x, y), textcoords="offset points", xytext=(4, 4), fontsize=8)
    ax.set_xscale("log")
    ax.set_xlabel("wall time per sequence [s]")
    ax.set_ylabel("mean Fréchet distance [m]")
    ax.set_title(f"{robot.name}, {settings.mode} mode: similarity against time († = self-collision)")
    fig.tight_layout()
    path = results_doc.figure_path(f"{robot.name}_methods_{settings.mode}.png")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return ev, path


# ---------------------------------------------------------------------- initialisation ablation
def _frechet(robot, demo, q) -> float:
    return tracking_errors(demo, robot, q.detach().cpu().double().numpy())["frechet_m"]


def init_ablation(robot, model, demos, budgets=BUDGETS):
    """Fréchet at each budget and the loss curve per initialisation (+ joint space at the budgets)."""
    from tqdm.auto import tqdm

    top = max(budgets)
    inputs = [RetargetInputs.from_demonstration(d, dtype=robot.lower_limits.dtype) for d in demos]
    targets = [x.targets for x in inputs]
    frames = np.array([len(d) for d in demos], dtype=float)
    rows, curves = {}, {}
    bar = tqdm(total=len(INITS) * len(demos), desc="init ablation", file=sys.stderr, leave=False)
    for label, kw in INITS.items():
        fr = {b: [] for b in budgets}
        secs = {b: 0.0 for b in budgets}
        hist = np.zeros(top + 1)
        for demo, x in zip(demos, inputs, strict=True):
            for b in budgets:
                r = optimize_latent(model, robot, x.targets, OptimizeSettings(iterations=b, patience=NO_STOP, **kw), weights=PAPER,
                                    encoder_input=x.encoder, fast=True)
                fr[b].append(_frechet(robot, demo, r.q))
                secs[b] += r.seconds
                if b == top:
                    hist += np.asarray(r.history) * len(demo)  # per-frame mean, frame weighted
            bar.update(1)
        rows[label] = {b: (float(np.mean(fr[b])), secs[b]) for b in budgets}
        curves[label] = hist / frames.sum()
    bar.close()
    joint = {}
    for b in budgets:
        vals, t = [], 0.0
        for demo, tg in zip(demos, targets, strict=True):
            r = optimize_joints(robot, tg, JointOptimizeSettings(iterations=b, patience=NO_STOP), weights=PAPER, fast=True)
            vals.append(_frechet(robot, demo, r.q))
            t += r.seconds
        joint[b] = (float(np.mean(vals)), t)
    rows["joint space (ref.)"] = joint

    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 3.5))
    for label, c in curves.items():
        ax.plot(np.arange(len(c)), c, label=label)
    ax.set_yscale("log")
    ax.set_xlabel("iteration")
    ax.set_ylabel("mean loss (objective + ||z||²)")
    ax.set_title(f"{robot.name}: latent optimisation by initialisation")
    ax.legend(fontsize=8)
    fig.tight_layout()
    loss_png = results_doc.figure_path(f"{robot.name}_init_loss.png")
    fig.savefig(loss_png, dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6, 3.5))
    for label, row in rows.items():
        ax.plot(list(row), [v[0] for v in row.values()], marker="o", label=label, linestyle="--" if "joint" in label else "-")
    ax.set_xlabel("iterations (budget)")
    ax.set_ylabel("mean Fréchet distance [m]")
    ax.set_title(f"{robot.name}: Fréchet distance at each budget")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fr_png = results_doc.figure_path(f"{robot.name}_init_frechet.png")
    fig.savefig(fr_png, dpi=110)
    plt.close(fig)
    return rows, curves, loss_png, fr_png


# ---------------------------------------------------------------------- Table III
VARIANTS = (("AE", "mlp", "supervised"), ("GAE", "graph", "supervised"), ("AE+FK", "mlp", "fk"), ("GAE+FK", "graph", "fk"))


def table3(robot, demos, train_steps: int, iterations: int):
    """Train the four variants for the same number of steps; Init and Optim Fréchet per sequence."""
    data, labels, _ = supervised_dataset(robot, SupervisedSettings(), progress=True)
    val = corpus_inputs("train").index(slice(2, None, 16)).index(slice(0, 600))  # train frames not in `data`
    results, trained = {}, {}
    for name, kind, objective in VARIANTS:
        print(f"Table III: training {name} ({kind}, {objective}) for {train_steps} steps ...", file=sys.stderr)
        model, secs, steps = train_variant(robot, name, data, labels, steps=train_steps, val_data=val, weights=PAPER)
        trained[name] = (secs, steps)
        per = {"Init": {}, "Optim": {}}
        for demo in demos:
            x = RetargetInputs.from_demonstration(demo, dtype=robot.lower_limits.dtype)
            for col, iters in (("Init", 0), ("Optim", iterations)):
                r = optimize_latent(model, robot, x.targets, OptimizeSettings(init="encoder", iterations=iters), weights=PAPER,
                                    encoder_input=x.encoder, fast=True)
                q = r.q.detach().cpu().double().numpy()
                objective = float((r.loss - PAPER.latent * r.z.pow(2).flatten(1).sum(1)).mean())  # without the prior
                per[col][demo.name] = (tracking_errors(demo, robot, q)["frechet_m"], self_collision_frames(robot, q) > 0, r.seconds, objective)
        results[name] = per
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 3.5))
    cols = [(n, c) for n, *_ in VARIANTS for c in ("Init", "Optim")]
    ax.boxplot([[v[0] for v in results[n][c].values()] for n, c in cols], tick_labels=[f"{n}\n{c}" for n, c in cols])
    ax.set_ylabel("Fréchet distance [m]")
    ax.set_title(f"{robot.name}: architecture and objective ablation (test sequences)")
    ax.tick_params(axis="x", labelsize=7)
    fig.tight_layout()
    png = results_doc.figure_path(f"{robot.name}_table3.png")
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return results, trained, png, len(data)


# ---------------------------------------------------------------------- report
MODE_TEXT = {
    "paper": "the paper's objective (no smoothness term: frames independent), no retiming",
    "robot-ready": "the shipped defaults of `nlo-lab retarget` (smoothness term, warm start along the sequence; the latent"
                   " methods' output retimed to the joint velocity limits, so their velocity violations are counted on the retimed time base)",
}


def _yes(ok: bool) -> str:
    return "yes" if ok else "**no**"


def _ablation_iters(args) -> int:
    """The ablations' budget (the paper's objective, Adam): ``--iters``, else the paper's 100."""
    return args.iters if args.iters is not None else PAPER_ITERATIONS


def _budget_text(args, mode: str) -> str:
    if args.iters is not None:
        return f"Latent and joint-space methods: {args.iters} steps (latent: {'Adam' if mode == 'paper' else 'Rprop'}), patience 5 for Adam"
    if mode == "paper":
        return f"Latent and joint-space methods: the paper's {PAPER_ITERATIONS} Adam steps, patience 5"
    return (f"Latent methods: the pipeline's {OptimizeSettings().iterations} Rprop steps (`OptimizeSettings()`, docs/DESIGN.md),"
            f" then its hand stage; joint-space: {PAPER_ITERATIONS} Adam steps, patience 5")


def report_table1(robot, args, notes, ev, png, mode) -> str:
    m = "latent_encoder"
    out = results_doc.heading(f"## Table I on {robot.name}, {mode} mode", notes)
    out += [
        f"Mode: {MODE_TEXT[mode]}. {len(ev.sequences)} test sequences.",
        "",
        "Mean of wrist and elbow discrete Fréchet distances [m] after mapping the human into the robot frame;"
        " `*` = the method's motion has at least one self-collision frame in that sequence. Wall time summed"
        f" over the sequences. {_budget_text(args, mode)}; `latent_random`"
        " starts from N(0, 1) (σ = 1, the latent prior). `nn_supervised`'s labelling and training time is not part of its wall time"
        + (f" (labels {ev.info['nn_label_seconds']:.0f} s, training {ev.info['nn_train_seconds']:.0f} s, once)." if ev.info.get("nn_train_seconds") else "."),
        "",
        format_table(ev, markdown=True),
        "",
        f"![methods]({results_doc.relative(png)})",
        "",
    ]
    best = min(ev.methods, key=lambda k: ev.mean(k))
    better = [k for k in ev.methods if k != m and ev.mean(k) < ev.mean(m)]
    gain = 1 - ev.mean(m) / ev.mean("encoder_only") if "encoder_only" in ev.methods else float("nan")
    coll_frames = int(ev.total(m, "collision_frames"))
    out += [
        "#### Targets (docs/DESIGN.md) against the measurement",
        "",
        "| target | measured | met |",
        "|---|---|---|",
        f"| zero joint-limit violations ({m}) | {int(ev.total(m, 'limit_violations'))} | {_yes(ev.total(m, 'limit_violations') == 0)} |",
        f"| zero self-collision frames ({m}) | {coll_frames} frames in {ev.collision_sequences(m)} sequences | {_yes(coll_frames == 0)} |",
        f"| {m} ≥ 10 % below encoder_only in mean Fréchet | {100 * gain:.1f} % below | {_yes(gain >= 0.10)} |",
        "",
        f"Lowest mean Fréchet distance: **{best}** ({ev.mean(best):.4f} m); {m}: {ev.mean(m):.4f} m."
        + (f" Methods with a lower mean than {m}: {', '.join(f'{k} ({ev.mean(k):.4f} m, {ev.collision_sequences(k)} sequences with self-collision)' for k in better)}."
           if better else f" No method has a lower mean than {m}."),
        "",
    ]
    return "\n".join(out)


def report_init(robot, args, notes, abl) -> str:
    rows, curves, loss_png, fr_png, n = abl
    budgets = list(next(iter(rows.values())))
    out = results_doc.heading(f"## Initialisation ablation on {robot.name} (first {n} test sequences)", notes)
    out += [
        "Mean Fréchet distance [m] (and summed wall time [s]) after each budget of Adam steps on the paper's objective"
        " (no smoothness term); every budget is a separate run with no early stop. The random starts are the paper's"
        " Gaussians of variance 0.1 and 0.2 (σ = √0.1 = 0.32 and √0.2 = 0.45); train-stats: N(mean, std²) of the"
        " encoder's latents over the training frames. Joint-space optimisation from the neutral pose at the same budgets for reference.",
        "",
        "| initialisation | " + " | ".join(f"{b} it" for b in budgets) + " |",
        "|---|" + "---|" * len(budgets),
    ]
    for label, row in rows.items():
        out.append(f"| {label} | " + " | ".join(f"{v[0]:.4f} ({v[1]:.1f} s)" for v in row.values()) + " |")
    enc = rows["encoder"]
    randoms = [k for k in rows if k not in ("encoder", "joint space (ref.)")]
    wins = {b: all(enc[b][0] < rows[k][b][0] for k in randoms) for b in budgets}
    out += [
        "",
        "| target | measured | met |",
        "|---|---|---|",
        "| encoder initialisation better than random initialisation at every budget | "
        + ", ".join(f"{b}: {'better' if w else 'not better'}" for b, w in wins.items())
        + f" | {_yes(all(wins.values()))} |",
        "",
        "Final mean loss after "
        + f"{len(next(iter(curves.values()))) - 1} iterations: "
        + ", ".join(f"{k} {c[-1]:.2f}" for k, c in curves.items())
        + ".",
        "",
        f"![loss against iteration]({results_doc.relative(loss_png)}) ![Fréchet against budget]({results_doc.relative(fr_png)})",
        "",
    ]
    return "\n".join(out)


def report_table3(robot, args, notes, t3) -> str:
    results, trained, png, n_train, n = t3
    names = [v[0] for v in VARIANTS]
    seqs = list(next(iter(results.values()))["Init"])
    out = results_doc.heading(f"## Table III on {robot.name}: architecture and objective (first {n} test sequences)", notes)
    out += [
        f"All four variants trained in this run on the same {n_train} training frames (every 4th frame of the train"
        f" split), for the same {args.train_steps} optimiser steps of batch 64 each (seed 0); supervised variants fit the"
        " joint-space optimisation labels of `nn_supervised` (normalised squared angle error), FK variants minimise"
        " the objective (paper Eq. 10). 'Init' = encoder output decoded, 'Optim' = + latent optimisation"
        f" ({_ablation_iters(args)} Adam steps, patience 5, the paper's objective). `*` = self-collision in the sequence. These are reduced"
        " budgets: the shipped model (Table I) is trained longer. docs/PAPER.md discusses how this differs from the paper's table.",
        "",
        "| sequence | " + " | ".join(f"{nm} {c}" for nm in names for c in ("Init", "Optim")) + " |",
        "|---|" + "---|" * (2 * len(names)),
    ]
    for s in seqs:
        cells = []
        for nm in names:
            for c in ("Init", "Optim"):
                f, coll, *_ = results[nm][c][s]
                cells.append(f"{f:.4f}{'*' if coll else ''}")
        out.append(f"| {s} | " + " | ".join(cells) + " |")
    means = [f"{np.mean([v[0] for v in results[nm][c].values()]):.4f}" for nm in names for c in ("Init", "Optim")]
    out.append("| **mean** | " + " | ".join(means) + " |")
    colls = [str(sum(1 for v in results[nm][c].values() if v[1])) for nm in names for c in ("Init", "Optim")]
    out.append("| **collision seq.** | " + " | ".join(colls) + " |")
    objs = [f"{np.mean([v[3] for v in results[nm][c].values()]):.1f}" for nm in names for c in ("Init", "Optim")]
    out.append("| **objective** | " + " | ".join(objs) + " |")
    out.append("| **train s / steps** | " + " | ".join(f"{trained[nm][0]:.0f} s / {trained[nm][1]}" for nm in names for _ in (0, 1)) + " |")
    out += ["", f"![Table III]({results_doc.relative(png)})", ""]
    return "\n".join(out)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--robot", default="yumi")
    p.add_argument("--limit", type=int, default=None, help="Table I: first N test sequences (default all)")
    p.add_argument("--ablation-limit", type=int, default=8, help="init ablation and Table III: first N test sequences")
    p.add_argument("--iters", type=int, default=None,
                   help="budget of the latent and joint-space methods (default: each method's: in robot-ready mode the pipeline's"
                        " 40 Rprop steps, in paper mode the paper's 100 Adam steps, joint_space 100; the ablations 100)")
    p.add_argument("--modes", default=",".join(EVALUATION_MODES), help=f"Table I's modes, comma list of {', '.join(EVALUATION_MODES)}")
    p.add_argument("--train-steps", type=int, default=4000, help="Table III: optimiser steps (batch 64) per variant")
    p.add_argument("--train-seconds", type=float, default=240.0, help="only without a shipped checkpoint: training time of the model [s]")
    p.add_argument("--threads", type=int, default=1, help="torch threads (1: no oversubscription on a shared 2-core machine)")
    p.add_argument("--quick", action="store_true", help="4 sequences, 3 in the ablations, 30 training steps per variant")
    p.add_argument("--skip", default="", help="comma list of parts to skip: table1,init,table3")
    p.add_argument("--no-write", action="store_true", help="print only; leave the results file alone")
    args = p.parse_args(argv)
    if args.no_write:
        results_doc.draft_figures()
    if args.quick:
        args.limit = args.limit or 4
        args.ablation_limit = min(args.ablation_limit, 3)
        args.train_steps = min(args.train_steps, 30)
    skip = {s.strip() for s in args.skip.split(",") if s.strip()}
    modes = [m.strip() for m in args.modes.split(",") if m.strip()]
    unknown = [m for m in modes if m not in EVALUATION_MODES]
    if unknown:
        p.error(f"unknown mode(s) {unknown}; expected some of {EVALUATION_MODES}")
    torch.set_num_threads(max(1, args.threads))
    robot = load_robot(args.robot)
    notes: list[str] = []
    demos = sign_corpus("test")
    model = _model(robot, args.train_seconds, notes)
    sections: dict[str, str] = {}
    if "table1" not in skip:
        network = supervised_network(robot, BaselineSettings().supervised, progress=True)
        for mode in modes:
            t0 = time.perf_counter()
            settings = BaselineSettings(iterations=args.iters, mode=mode)
            ev, png = table1(robot, demos[: args.limit] if args.limit else demos, settings, model, network)
            note = f"run time {time.perf_counter() - t0:.0f} s; torch threads {torch.get_num_threads()}"
            sections[f"table1:{robot.name}:{mode}"] = report_table1(robot, args, [*notes, note], ev, png, mode)
    sub = demos[: args.ablation_limit]
    if "init" not in skip:
        t0 = time.perf_counter()
        rows, curves, loss_png, fr_png = init_ablation(robot, model, sub, tuple(b for b in BUDGETS if b <= _ablation_iters(args)))
        for label, row in rows.items():
            print(f"{label:>28}: " + "  ".join(f"{b}:{v[0]:.4f}" for b, v in row.items()))
        note = f"run time {time.perf_counter() - t0:.0f} s"
        sections[f"init:{robot.name}"] = report_init(robot, args, [*notes, note], (rows, curves, loss_png, fr_png, len(sub)))
    if "table3" not in skip:
        t0 = time.perf_counter()
        results, trained, png, n_train = table3(robot, sub, args.train_steps, _ablation_iters(args))
        for nm, per in results.items():
            print(f"{nm:>8}: Init {np.mean([v[0] for v in per['Init'].values()]):.4f}  Optim {np.mean([v[0] for v in per['Optim'].values()]):.4f}")
        note = f"run time {time.perf_counter() - t0:.0f} s (labels cached after the first run)"
        sections[f"table3:{robot.name}"] = report_table3(robot, args, [*notes, note], (results, trained, png, n_train, len(sub)))
    results_doc.publish(sections, not args.no_write)
    if not args.no_write and sections:
        results_doc.remove_section(f"quality:{robot.name}")  # the one section of the benchmark before the split
    return 0


if __name__ == "__main__":
    sys.exit(main())
