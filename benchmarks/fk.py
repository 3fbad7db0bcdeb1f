"""FK speed: nlo_lab's batched FK against calling pytorch-kinematics on the same URDF.

Prints forward and forward+backward wall time (median of many runs) at batch 1,
32 and 256 for YuMi with both hands (all 26 actuated angles; pytorch-kinematics
gets every moving joint, the 12 mimic joints set explicitly from their sources).

Run: ``.venv/bin/python benchmarks/fk.py [--robot yumi] [--runs 50] [--threads N] [--no-write]``;
writes the section ``fk:ROBOT`` of docs/RESULTS.md.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import torch

from nlo_lab.robot import load_robot

sys.path.insert(0, str(Path(__file__).resolve().parent))
import results_doc  # noqa: E402


def median_ms(fn, runs: int) -> float:
    for _ in range(5):  # warm-up
        fn()
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="yumi")
    parser.add_argument("--runs", type=int, default=50)
    parser.add_argument("--threads", type=int, default=None, help="torch.set_num_threads (default: torch's choice)")
    parser.add_argument("--no-write", action="store_true", help="print only; leave docs/RESULTS.md alone")
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    from nlo_lab.robot.pk_chain import PKChain

    robot = load_robot(args.robot)
    pk_ref = PKChain(robot, dtype=torch.float32)  # the same URDF as a pytorch-kinematics chain, mimic joints expanded
    tree = robot.tree

    def pk_fk(q):
        return pk_ref.chain.forward_kinematics(pk_ref.angles(q))

    print(f"FK of {robot.name}: {robot.n_joints} actuated, {len(tree.moving_names)} moving joints, {len(robot.link_names)} links; "
          f"torch {torch.__version__}, {torch.get_num_threads()} threads, float32, CPU, median of {args.runs} runs")  # fmt: skip
    header = f"{'batch':>5} | {'ours fwd ms':>11} | {'pk fwd ms':>9} | {'ratio':>5} | {'ours f+b ms':>11} | {'pk f+b ms':>9} | {'ratio':>5}"
    print(header)
    print("-" * len(header))
    rows, ratios = [], {"forward": [], "forward+backward": []}
    g = torch.Generator().manual_seed(0)
    for batch in (1, 32, 256):
        q0 = robot.lower_limits + torch.rand(batch, robot.n_joints, generator=g) * (robot.upper_limits - robot.lower_limits)

        def ours_fwd(q0=q0):  # this batch's poses
            with torch.no_grad():
                robot.forward_kinematics(q0)

        def pk_fwd(q0=q0):  # this batch's poses
            with torch.no_grad():
                pk_fk(q0)

        def ours_fb(q0=q0):  # this batch's poses
            q = q0.clone().requires_grad_(True)
            T = robot.forward_kinematics_tensor(q)
            T[..., :3, 3].square().sum().backward()

        def pk_fb(q0=q0):  # this batch's poses
            q = q0.clone().requires_grad_(True)
            out = pk_fk(q)
            sum(t.get_matrix()[..., :3, 3].square().sum() for t in out.values()).backward()

        # same numbers from both (positions of every link)
        ours = robot.forward_kinematics(q0)
        ref = pk_fk(q0)
        err = max(float((ours[n] - ref[n].get_matrix()).abs().max()) for n in robot.link_names)
        assert err < 1e-4, f"pytorch-kinematics and nlo_lab disagree by {err}"
        a, b = median_ms(ours_fwd, args.runs), median_ms(pk_fwd, args.runs)
        c, d = median_ms(ours_fb, args.runs), median_ms(pk_fb, args.runs)
        print(f"{batch:>5} | {a:>11.3f} | {b:>9.3f} | {b / a:>5.1f} | {c:>11.3f} | {d:>9.3f} | {d / c:>5.1f}")
        ratios["forward"].append(b / a)
        ratios["forward+backward"].append(d / c)
        rows.append(f"| {batch} | {a:.3f} | {b:.3f} | {b / a:.1f} | {c:.3f} | {d:.3f} | {d / c:.1f} |")
    print("ratio = pytorch-kinematics time / ours (> 1: ours is faster)")
    if not args.no_write:
        text = "\n".join([
            f"## Forward kinematics on {robot.name} against pytorch-kinematics", "", results_doc.stamp(),
            f"{robot.n_joints} actuated angles, {len(tree.moving_names)} moving joints, {len(robot.link_names)} links; float32, "
            f"median of {args.runs} runs. pytorch-kinematics gets the mimic joints expanded by `nlo_lab.robot.pk_chain.PKChain`; "
            "both give the same poses on every link (asserted here; the tests check every robot to 1e-6 m, gradients included).",
            "", "| batch | ours fwd ms | pk fwd ms | ratio | ours fwd+bwd ms | pk fwd+bwd ms | ratio |", "|---:|---:|---:|---:|---:|---:|---:|",
            *rows, "",
            "Why ours is faster: pytorch-kinematics composes the tree in a Python loop over the links (a few 4×4 products, "
            "index look-ups and a `Transform3d` per link, on every call); ours folds the constant offsets in once at load "
            "time, forms every joint's local transform with one matrix product (Rodrigues' formula is linear in sin θ and "
            "cos θ) and composes the chain by pointer jumping in ⌈log₂(depth + 1)⌉ batched products. "
            + trend(ratios),
        ])  # fmt: skip
        print(f"wrote {results_doc.update_section(f'fk:{robot.name}', text)}")


def trend(ratios: dict[str, list[float]]) -> str:
    """Whether each ratio shrinks as the batch grows, said from the measured figures."""
    said = []
    for name, r in ratios.items():
        figures = " → ".join(f"{x:.1f}" for x in r)
        shrinks = all(later < earlier for earlier, later in zip(r, r[1:], strict=False))
        said.append(f"the {name} ratio {'shrinks' if shrinks else 'does not shrink steadily'} ({figures})")
    return ("As the batch grows the arithmetic takes a larger share of the time and per-call overhead a smaller one; "
            "in this run " + " and ".join(said) + ".")


if __name__ == "__main__":
    main()
