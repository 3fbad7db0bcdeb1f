"""Round trip on every robot: random feasible pose -> FK -> human targets -> retarget.

The targets are the robot's own role points (shoulder, elbow, wrist, wrist
orientation, finger base/tip), so a perfect retargeting reproduces the pose's
wrist and elbow positions. Retargeting is neural latent optimisation with the
shipped checkpoint (encoder initialisation, Adam on z, decoder frozen).

Stated tolerance (positions relative to the shoulder, as a fraction of the
robot's zero-pose arm length l = upper + fore): over 48 random poses x 2 arms,
the median wrist error <= 5 % of l and the median elbow error <= 10 % of l, and
the optimisation lowers the objective to below a tenth of its start.
Random poses are drawn in the middle 60 % of every joint range (margin 20 %),
collision-free (every checked pair at least its d_min apart); they are far
outside the training distribution of the encoder (human signing), so the budget
is 300 iterations with patience 20 (lr 0.03).

Why 48 poses and a median: not every random pose is recovered. NAO recovers
nearly all of them exactly, Pepper about 80-90 %, YuMi (7 joints per arm and
wide wrist ranges) about 60-70 % within 5 % of l; the rest end in a local
minimum (measured over seeds 7-10: YuMi's median wrist error 0.023-0.033 l,
elbow 0.064-0.075 l). With 8 poses, swapping a single pose moved YuMi's
median across the tolerance, so 8 was a coin toss, not a test.
"""

from __future__ import annotations

import pytest
import torch

from nlo_lab.inference import OptimizeSettings, optimize_latent
from nlo_lab.model import encoder_input, load_pretrained
from nlo_lab.objective import LossWeights, point_plan, robot_points, targets_from_demonstration
from nlo_lab.robot import load_robot

WRIST_TOL = 0.05  # fraction of the arm length, median over poses and arms
ELBOW_TOL = 0.10


def _relative(robot, q):
    pts = robot_points(robot, robot.forward_kinematics(q))
    return pts["wrist"] - pts["shoulder"], pts["elbow"] - pts["shoulder"]  # (T, 2, 3) each


# YuMi's case is a known failure since its capsules were fitted to the URDF's collision geometry (430e5cc,
# refined in e509c20 and ff9fafd: 13 capsules and 45 pairs became 50 capsules and 304 pairs) while the shipped
# yumi.pt is still the checkpoint trained with the old capsules: from the encoder's guess the collision term holds
# the arms in a local minimum (median wrist error 0.085-0.128 of the arm length on 2026-11-26; 0.037 with the
# collision term off; 0.066 once the body's boxes were tiled with capsules, assets/robots/YUMI.md, and 0.149 with
# the hand weights of 33b4ab5: the encoder's guesses start deep in the capsules, and the results end on a wrist
# branch that joint 5's pair blocks; a retrain on the tiled capsules ends at 0.060, elbow 0.140: not shipped). A retrain on the fitted capsules has not yet given a checkpoint that beats the shipped one
# (assets/checkpoints/README.md). strict: the day a checkpoint recovers the poses, this case fails and must be
# turned back into a plain test.
YUMI_KNOWN_FAILURE = pytest.mark.xfail(
    strict=True, reason="yumi.pt predates YuMi's fitted capsules: the round trip ends in a local minimum (assets/checkpoints/README.md)")


@pytest.mark.slow
@pytest.mark.parametrize("name", [pytest.param("yumi", marks=YUMI_KNOWN_FAILURE), "nao", "pepper"])
def test_round_trip_recovers_wrist_and_elbow(name, demonstration_from_robot, random_feasible_pose):
    robot = load_robot(name)
    model = load_pretrained(robot)
    q = random_feasible_pose(robot, 48, seed=7, margin=0.2)
    demo = demonstration_from_robot(robot, q)
    targets = targets_from_demonstration(demo)
    # 48 independent random poses, not a motion: no smoothness term between them
    result = optimize_latent(model, robot, targets, OptimizeSettings(init="encoder", iterations=300, patience=20, lr=0.03),
                             weights=LossWeights(smooth=0.0), encoder_input=encoder_input(demo))
    assert min(result.history) < 0.1 * result.history[0]
    assert (result.q >= robot.lower_limits).all() and (result.q <= robot.upper_limits).all()
    with torch.no_grad():
        w0, e0 = _relative(robot, q)
        w1, e1 = _relative(robot, result.q)
    length = point_plan(robot, q.dtype, q.device).arm_length  # (2,)
    wrist_err = ((w1 - w0).norm(dim=-1) / length).median().item()
    elbow_err = ((e1 - e0).norm(dim=-1) / length).median().item()
    assert wrist_err <= WRIST_TOL, f"{name}: median wrist error {wrist_err:.3f} of the arm length"
    assert elbow_err <= ELBOW_TOL, f"{name}: median elbow error {elbow_err:.3f} of the arm length"
