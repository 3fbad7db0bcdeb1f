"""What YuMi's Inspire hands can do on the handshape measures, by exhaustive search: per frame, and within the hand stage's speed clamp.

    python benchmarks/hands_frontier.py [--weights 1,0.2,0.5,0.2 ...] [--no-video] [--stage]

A diagnostic for ``benchmarks/hands.py`` (issue 27), not a method: it asks how far the hand stage is from the best
handshapes this 6-actuator hand can take, and what stops it. Each finger but the thumb moves with one actuated joint
(its distal joint mimics it), the thumb with two, and a hand's capsule pairs join the thumb to its palm, to itself
and to each other finger. So once the thumb is placed every other finger is a one-joint problem of its own: over
grids of the joints (``--finger-grid`` values per finger, ``--thumb-grid``² thumb cells) the search is exhaustive.

The cost of a hand-frame is the measures themselves (``nlo_lab.evaluation.hands``), in degrees, weighted
``a, b, c, d``: ``a`` x wrist->tip (mean of five), ``b`` x thumb->tips (mean of four), ``c`` x base->tip (mean of
five), and ``d`` x 57.3 x the thumb-index tip distance off the human's (hand lengths; the pinch measure is their
correlation). A capsule pair that penetrates rules a cell out. Two searches:

* **per frame**: each hand-frame's cheapest cell (the thumb's cell, and each finger's value given it); and the same
  held to the hand stage's speed clamp afterwards (``within_speed``, as the stage does with its own result);
* **within the clamp**: over the whole trajectory of each hand, every joint's step between frames within the hand
  stage's caps (``nlo_lab.inference.hand_stage.step_caps`` of the latent optimisation's output, the start of the
  stage), by dynamic programming over the grid (Viterbi: the thumb's path given the fingers, then each finger's given
  the thumb, ``--sweeps`` times, from the start's own values). Frames that are not hand-frames cost nothing.

Both on the frames' arms of the latent optimisation (shipped ``yumi.pt``, default weights and settings), scored with
``hand_scores``. ``--stage``: then the pipeline's hand stage (``refine_hands``, the default settings) from the
clamped search's hands (its own speed clamp then from those hands, no looser than the latent optimisation's). Prints a table; writes nothing.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import torch
from scipy.ndimage import minimum_filter

sys.path.insert(0, str(Path(__file__).resolve().parent))
from hands import hand_joints, recordings  # noqa: E402

from nlo_lab.evaluation.hands import HandScores, angle_deg, hand_frames_mask, hand_scores  # noqa: E402
from nlo_lab.inference import OptimizeSettings  # noqa: E402
from nlo_lab.inference.hand_stage import hand_joint_mask, refine_hands, step_caps, within_speed  # noqa: E402
from nlo_lab.model import load_pretrained  # noqa: E402
from nlo_lab.objective import LossWeights, point_plan, targets_from_demonstration  # noqa: E402
from nlo_lab.pipeline import RetargetConfig  # noqa: E402
from nlo_lab.robot import load_robot  # noqa: E402

FINGERS = ("index", "middle", "ring", "pinky")
DEGREES = 180.0 / np.pi  # the distance term's scale: one hand length costs what one radian of angle does


class HandGrid:
    """One hand's fingertips and finger bases over grids of its joints, in its wrist frame, and the cells the
    capsule pairs allow.

    Attributes:
        finger_tip, finger_base: ``(G, 4, 3)`` index..pinky at each of the G values of their joint [m];
        thumb_tip, thumb_base: ``(C, 3)`` at each of the C = g² thumb cells (yaw-major);
        finger_ok: ``(C, G, 4)`` no capsule pair of the thumb and that finger penetrates;
        thumb_ok: ``(C,)`` no pair of the thumb with the palm or itself penetrates;
        values: per joint (thumb yaw, pitch, index..pinky) its grid [rad]; length: the hand length [m].
    """

    def __init__(self, robot, side: int, finger_grid: int, thumb_grid: int):
        joints = hand_joints(robot)[side]
        lo, hi = robot.lower_limits.double().numpy()[joints], robot.upper_limits.double().numpy()[joints]
        self.joints = joints
        self.values = [np.linspace(lo[k], hi[k], thumb_grid if k < 2 else finger_grid) for k in range(6)]
        rb = robot.to(dtype=torch.float64)
        plan = point_plan(rb, torch.float64)
        neutral = rb.neutral_q.numpy()
        yaw, pitch, value = np.meshgrid(np.arange(thumb_grid), np.arange(thumb_grid), np.arange(finger_grid), indexing="ij")
        q = np.tile(neutral, (yaw.size, 1))  # every thumb cell x every finger value (all four fingers at that value)
        q[:, joints[0]], q[:, joints[1]] = self.values[0][yaw.ravel()], self.values[1][pitch.ravel()]
        for k in range(2, 6):
            q[:, joints[k]] = self.values[k][value.ravel()]
        cells, G = thumb_grid * thumb_grid, finger_grid
        hand = "lr"[side]
        pairs = robot.spec.collision_pairs
        own = [i for i, (a, b) in enumerate(pairs) if f"_hand_{hand}_" in a and f"_hand_{hand}_" in b]
        if not own or not all("thumb" in pairs[i][0] or "thumb" in pairs[i][1] for i in own):
            raise SystemExit("hands_frontier: the search needs YuMi's hand pairs (each pair joins the thumb to another part)")
        with_finger = {f: [i for i in own if any(f in name for name in pairs[i])] for f in FINGERS}
        rest = [i for i in own if not any(i in v for v in with_finger.values())]  # the thumb with the palm, with itself
        with torch.no_grad():
            distance = np.concatenate([rb.capsule_distances(rb.forward_kinematics(torch.as_tensor(chunk)))[:, own].numpy()
                                       for chunk in np.array_split(q, max(1, len(q) // 4096))]).reshape(cells, G, -1)
            col = {i: c for c, i in enumerate(own)}
            self.finger_ok = np.stack([(distance[..., [col[i] for i in with_finger[f]]] >= 0).all(-1) for f in FINGERS], -1)
            self.thumb_ok = (distance[:, 0, [col[i] for i in rest]] >= 0).all(-1)
            points = plan(torch.as_tensor(q[::G]))  # the thumb cells (finger value 0)
            tip, base = self._wrist_frame(plan, points, side)
            self.thumb_tip, self.thumb_base = tip[:, 0], base[:, 0]
            points = plan(torch.as_tensor(q[:G]))  # the finger values (thumb cell 0)
            tip, base = self._wrist_frame(plan, points, side)
            self.finger_tip, self.finger_base = tip[:, 1:], base[:, 1:]
        self.length = float(plan.hand_length[side])

    @staticmethod
    def _wrist_frame(plan, p, side: int) -> tuple[np.ndarray, np.ndarray]:
        """``(B, 5, 3)`` tips and bases of ``side``'s five fingers (thumb..pinky) in its wrist frame."""
        rows = [k for k in range(len(plan.finger_side)) if int(plan.finger_side[k]) == side]
        rows = sorted(rows, key=lambda k: int(plan.finger_index[k]))
        rotation, wrist = p.wrist_rotation[:, side].numpy(), p.wrist[:, side].numpy()
        frame = lambda x: np.einsum("bji,bkj->bki", rotation, x - wrist[:, None])  # noqa: E731
        return frame(p.finger_tip[:, rows].numpy()), frame(p.finger_base[:, rows].numpy())


class FrameCost:
    """The cost of one hand-frame over the grid (see the module docstring): ``thumb (C,)`` the thumb's own part,
    ``finger(c) (G, 4)`` each finger's part with the thumb at cell ``c`` (infeasible cells cost ``inf``)."""

    def __init__(self, grid: HandGrid, human_tip: np.ndarray, human_base: np.ndarray, human_length: float, weights):
        a, b, c, d = weights
        self.grid, self.b, self.d = grid, b, d
        self.own = (a / 5) * angle_deg(grid.finger_tip, human_tip[None, 1:]) + (c / 5) * angle_deg(
            grid.finger_tip - grid.finger_base, (human_tip - human_base)[None, 1:])  # (G, 4)
        self.thumb = (a / 5) * angle_deg(grid.thumb_tip, human_tip[None, 0]) + (c / 5) * angle_deg(
            grid.thumb_tip - grid.thumb_base, (human_tip - human_base)[None, 0])
        self.thumb = np.where(grid.thumb_ok, self.thumb, np.inf)
        self.to_fingers = human_tip[1:] - human_tip[0]  # (4, 3)
        self.pinch = np.linalg.norm(self.to_fingers[0]) / human_length

    def finger(self, cells: np.ndarray) -> np.ndarray:
        """``(len(cells), G, 4)``: each finger's cost at each value with the thumb at each of ``cells``."""
        g = self.grid
        gap = g.finger_tip[None] - g.thumb_tip[cells][:, None, None]  # (n, G, 4, 3)
        cost = self.own[None] + (self.b / 4) * angle_deg(gap, self.to_fingers[None, None])
        cost[..., 0] += self.d * DEGREES * np.abs(np.linalg.norm(gap[..., 0, :], axis=-1) / g.length - self.pinch)
        return np.where(g.finger_ok[cells], cost, np.inf)


def per_frame(cost: FrameCost) -> tuple[int, np.ndarray]:
    """The cheapest thumb cell and finger values (4,) of one hand-frame."""
    every = cost.finger(np.arange(len(cost.thumb)))  # (C, G, 4)
    total = cost.thumb + every.min(1).sum(-1)
    cell = int(np.argmin(total))
    return cell, every[cell].argmin(0)


def viterbi(cost: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """The path of least summed cost through ``cost (T, *S)`` (a grid of states per frame) whose step between
    frames t and t+1 is at most ``reach[t] (T-1, len(S))`` grid steps along each axis: ``(T, len(S))`` indices."""
    T, shape = cost.shape[0], cost.shape[1:]
    best, before = cost[0], []
    for t in range(1, T):
        before.append(best)
        window = tuple(2 * int(r) + 1 for r in reach[t - 1])
        best = minimum_filter(best, size=window, mode="constant", cval=np.inf) + cost[t]
    path = [np.unravel_index(int(np.argmin(best)), shape)]
    for t in range(T - 2, -1, -1):  # back: the cheapest state within reach of the next one
        box = tuple(slice(max(0, i - int(r)), i + int(r) + 1) for i, r in zip(path[-1], reach[t], strict=True))
        local = np.unravel_index(int(np.argmin(before[t][box])), before[t][box].shape)
        path.append(tuple(s.start + i for s, i in zip(box, local, strict=True)))
    return np.array(path[::-1])


def within_clamp(grid: HandGrid, costs: list[FrameCost | None], start: np.ndarray, caps: np.ndarray, sweeps: int) -> np.ndarray:
    """``(T, 6)`` grid indices (thumb yaw, pitch, index..pinky) of one hand over the whole trajectory, each step
    within ``caps (T-1, 6)`` [rad]; ``costs[t]`` None: not a hand-frame. ``start (T, 6)`` [rad]: the first fingers."""
    T, n = len(costs), len(grid.thumb_tip)
    thumb_grid = len(grid.values[0])
    steps = np.array([v[1] - v[0] for v in grid.values])
    reach = np.floor(caps / steps + 1e-9).astype(int)  # whole grid steps within the cap
    index = np.stack([np.abs(grid.values[k][None] - start[:, k, None]).argmin(1) for k in range(6)], 1)
    for _ in range(sweeps):
        thumb = np.zeros((T, n))
        for t, c in enumerate(costs):
            if c is not None:
                thumb[t] = c.thumb + c.finger(np.arange(n))[:, index[t, 2:], np.arange(4)].sum(-1)
        path = viterbi(thumb.reshape(T, thumb_grid, thumb_grid), reach[:, :2])
        index[:, 0], index[:, 1] = path[:, 0], path[:, 1]
        cells = index[:, 0] * thumb_grid + index[:, 1]
        for k in range(4):
            finger = np.zeros((T, len(grid.values[2 + k])))
            for t, c in enumerate(costs):
                if c is not None:
                    finger[t] = c.finger(cells[t : t + 1])[0, :, k]
            index[:, 2 + k] = viterbi(finger, reach[:, 2 + k : 3 + k])[:, 0]
    return index


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--weights", nargs="+", default=["1,0.2,0.5,0.2", "1,0.15,0.4,0.3", "1,0.1,0.3,0.1"],
                    help="cost weights a,b,c,d (wrist->tip, thumb->tips, base->tip, thumb-index distance); one search each")
    ap.add_argument("--finger-grid", type=int, default=48, help="values of each finger's joint")
    ap.add_argument("--thumb-grid", type=int, default=24, help="values of each of the thumb's two joints")
    ap.add_argument("--sweeps", type=int, default=3, help="rounds of thumb path, then finger paths")
    ap.add_argument("--no-video", action="store_true", help="leave out the video (no MediaPipe)")
    ap.add_argument("--stage", action="store_true", help="then the pipeline's hand stage from the clamped search's hands")
    args = ap.parse_args()
    torch.set_num_threads(1)
    start_time = time.perf_counter()
    robot = load_robot("yumi")
    items = recordings(video=not args.no_video)
    latent = RetargetConfig(robot, model=load_pretrained(robot), weights=LossWeights()).build()
    starts = []
    for _, demo in items:  # the hand stage's start: the latent optimisation's output
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            starts.append(latent.optimize(latent.inputs(demo), hands=False).q.detach().double().numpy())
    grids = [HandGrid(robot, side, args.finger_grid, args.thumb_grid) for side in (0, 1)]
    rows = [("latent optimisation's hands (the stage's start)", [hand_scores(robot, q, d) for q, (_, d) in zip(starts, items, strict=True)])]
    for text in args.weights:
        weights = tuple(float(x) for x in text.split(","))
        frame_q, clamped_q, clamp_q = [], [], []
        for q0, (_, demo) in zip(starts, items, strict=True):
            mask, h_len = hand_frames_mask(demo), targets_from_demonstration(demo, dtype=torch.float64).hand_length[0].numpy()
            caps = step_caps(torch.as_tensor(q0), robot.velocity_limits.double(), float(demo.fps)).numpy()
            qf, qc = q0.copy(), q0.copy()
            for side, grid in enumerate(grids):
                if not mask[:, side].any():
                    continue
                costs: list[FrameCost | None] = [None] * len(demo)
                for t in np.flatnonzero(mask[:, side]):
                    R, w = demo.wrist_rotations[t, side], demo.arm_positions[t, side, 2]
                    tip, base = ((demo.finger_positions[t, side, :, e] - w) @ R for e in (1, 0))  # in the wrist frame
                    costs[t] = FrameCost(grid, tip, base, float(h_len[side]), weights)
                    cell, fingers = per_frame(costs[t])
                    index = (cell // len(grid.values[0]), cell % len(grid.values[0]), *fingers)
                    qf[t, grid.joints] = [grid.values[k][i] for k, i in enumerate(index)]
                index = within_clamp(grid, costs, q0[:, grid.joints], caps[:, grid.joints], args.sweeps)
                qc[:, grid.joints] = np.stack([grid.values[k][index[:, k]] for k in range(6)], 1)
            frame_q.append(qf)
            clamp_q.append(qc)
            hands = hand_joint_mask(robot).numpy()
            held = qf.copy()
            held[:, hands] = within_speed(torch.as_tensor(qf[:, hands]), torch.as_tensor(caps[:, hands])).numpy()
            clamped_q.append(held)
        rows.append((f"per frame, weights {text}", [hand_scores(robot, q, d) for q, (_, d) in zip(frame_q, items, strict=True)]))
        rows.append((f"per frame, then clamped, weights {text}", [hand_scores(robot, q, d) for q, (_, d) in
                                                                 zip(clamped_q, items, strict=True)]))
        rows.append((f"within the clamp, weights {text}", [hand_scores(robot, q, d) for q, (_, d) in zip(clamp_q, items, strict=True)]))
        if args.stage:
            settings = OptimizeSettings()
            staged = []
            for q, (_, demo) in zip(clamp_q, items, strict=True):
                t = targets_from_demonstration(demo, dtype=robot.lower_limits.dtype)
                out = refine_hands(robot, torch.as_tensor(q, dtype=robot.lower_limits.dtype), t, LossWeights(),
                                   iterations=settings.hand_iterations, patience=settings.patience, lr=settings.hand_lr, fast=True)
                staged.append(out.q.double().numpy())
            rows.append((f"within the clamp, weights {text}, then the hand stage", [hand_scores(robot, q, d) for q, (_, d) in
                                                                                    zip(staged, items, strict=True)]))
    print(f"{len(items)} recordings, grids: {args.finger_grid} per finger, {args.thumb_grid}² thumb cells; {time.perf_counter() - start_time:.0f} s")
    print("| search | wrist→tip | thumb→tips | base→tip | pinch r |\n|---|---|---|---|---|")
    for name, scores in rows:
        s = HandScores.cat(scores).summary()
        print(f"| {name} | {s['tip_deg']:.2f}° | {s['thumb_deg']:.2f}° | {s['finger_deg']:.2f}° | {s['pinch_r']:.3f} |")


if __name__ == "__main__":
    main()
