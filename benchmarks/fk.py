"""FK speed: nlo_lab's batched FK against calling pytorch-kinematics on the same URDF.

Prints forward and forward+backward wall time (median of many runs) at batch 1,
32 and 256 for YuMi with both hands (all 26 actuated angles; pytorch-kinematics
gets every moving joint, the 12 mimic joints set explicitly from their sources).

Run: ``.venv/bin/python benchmarks/fk.py [--robot yumi] [--runs 50] [--threads N]``
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch

from nlo_lab.robots import load_robot


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
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    import pytorch_kinematics as pk

    robot = load_robot(args.robot)
    chain = pk.build_chain_from_urdf(robot.spec.urdf.read_bytes())
    chain = chain.to(dtype=torch.float32)
    pk_names = chain.get_joint_parameter_names()
    # map our actuated angles to pk's full joint vector (mimic joints expanded the URDF's way)
    tree = robot.tree
    moving = {n: k for k, n in enumerate(tree.moving_names)}
    order = torch.tensor([moving[n] for n in pk_names])

    def pk_fk(q):
        full = tree.joint_angles(q).index_select(-1, order)  # (B, n_pk)
        return chain.forward_kinematics(full)

    print(f"FK of {robot.name}: {robot.n_joints} actuated, {len(tree.moving_names)} moving joints, {len(robot.link_names)} links; "
          f"torch {torch.__version__}, {torch.get_num_threads()} threads, float32, CPU, median of {args.runs} runs")  # fmt: skip
    header = f"{'batch':>5} | {'ours fwd ms':>11} | {'pk fwd ms':>9} | {'ratio':>5} | {'ours f+b ms':>11} | {'pk f+b ms':>9} | {'ratio':>5}"
    print(header)
    print("-" * len(header))
    g = torch.Generator().manual_seed(0)
    for batch in (1, 32, 256):
        q0 = robot.lower_limits + torch.rand(batch, robot.n_joints, generator=g) * (robot.upper_limits - robot.lower_limits)

        def ours_fwd():
            with torch.no_grad():
                robot.forward_kinematics(q0)

        def pk_fwd():
            with torch.no_grad():
                pk_fk(q0)

        def ours_fb():
            q = q0.clone().requires_grad_(True)
            T = robot.forward_kinematics_tensor(q)
            T[..., :3, 3].square().sum().backward()

        def pk_fb():
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
    print("ratio = pytorch-kinematics time / ours (> 1: ours is faster)")


if __name__ == "__main__":
    main()
