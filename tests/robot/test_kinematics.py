"""Forward kinematics: batched = looped, gradients, agreement with pytorch-kinematics (the reference) and yourdfpy, mimic joints."""

from __future__ import annotations

import logging
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import torch

from nlo_lab.robot import Robot, load_robot
from nlo_lab.rotations import matrix_to_rpy, rpy_to_matrix

yourdfpy = pytest.importorskip("yourdfpy")

ROBOTS = ["yumi", "nao", "pepper"]


def random_q(robot: Robot, batch: int, seed: int = 0) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    u = torch.rand(batch, robot.n_joints, generator=g, dtype=torch.float64)
    return robot.lower_limits + u * (robot.upper_limits - robot.lower_limits)  # (B, n) inside the limits


def test_rpy_round_trip():
    rng = np.random.default_rng(0)
    for rpy in rng.uniform([-3, -1.5, -3], [3, 1.5, 3], size=(20, 3)):
        np.testing.assert_allclose(matrix_to_rpy(rpy_to_matrix(rpy)), rpy, atol=1e-12)
    R = rpy_to_matrix([0.3, 0.0, 0.0])  # roll about x only
    np.testing.assert_allclose(R, [[1, 0, 0], [0, math.cos(0.3), -math.sin(0.3)], [0, math.sin(0.3), math.cos(0.3)]], atol=1e-15)


@pytest.mark.parametrize("name", ROBOTS)
def test_batched_equals_looped(name, robot64):
    robot = robot64(name)
    q = random_q(robot, 7, seed=1)
    T = robot.forward_kinematics_tensor(q)  # (7, L, 4, 4)
    for b in range(q.shape[0]):
        torch.testing.assert_close(T[b], robot.forward_kinematics_tensor(q[b : b + 1])[0], atol=1e-12, rtol=0)
        torch.testing.assert_close(T[b], robot.forward_kinematics_tensor(q[b]), atol=1e-12, rtol=0)
    # leading dimensions are kept; the dict holds every link
    assert robot.forward_kinematics_tensor(q.reshape(7, 1, -1)).shape == (7, 1, len(robot.link_names), 4, 4)
    poses = robot.forward_kinematics(q)
    assert set(poses) == set(robot.link_names)
    torch.testing.assert_close(poses[robot.link_names[-1]], T[:, -1])


@pytest.mark.parametrize("name", ROBOTS)
def test_float32_follows_float64(name, robot64):
    robot = load_robot(name)
    q = random_q(robot64(name), 5, seed=2)
    T32 = robot.forward_kinematics_tensor(q.float())
    assert T32.dtype == torch.float32
    # float32 rounding through ~10 chained rotations: a few 1e-7 relative
    torch.testing.assert_close(T32.double(), robot64(name).forward_kinematics_tensor(q), atol=2e-6, rtol=0)


@pytest.mark.parametrize("name", ROBOTS)
def test_gradient_matches_finite_differences(name, robot64):
    robot = robot64(name)
    q = random_q(robot, 2, seed=3).requires_grad_(True)
    idx = [robot.link_index(robot.arm(s).wrist) for s in ("left", "right")]
    if robot.has_fingers:
        idx += [robot.link_index(robot.arm(s).fingers[f][1]) for s in ("left", "right") for f in ("thumb", "middle")]

    def fk(q):
        return robot.forward_kinematics_tensor(q)[:, idx, :3, :]  # positions and rotations of a few links

    assert torch.autograd.gradcheck(fk, (q,), eps=1e-6, atol=1e-7, rtol=1e-5)


def yourdfpy_poses(robot: Robot, q: np.ndarray) -> list[dict[str, np.ndarray]]:
    """Independent FK: yourdfpy's own evaluation of the same URDF (mimic joints included)."""
    logging.getLogger("yourdfpy").setLevel(logging.ERROR)
    model = yourdfpy.URDF.load(str(robot.spec.urdf), build_scene_graph=True, load_meshes=False)
    assert set(model.actuated_joint_names) == set(robot.joint_names)
    out = []
    for row in q:
        model.update_cfg({n: float(v) for n, v in zip(robot.joint_names, row, strict=True)})
        out.append({link: model.get_transform(link, robot.spec.base_link) for link in robot.link_names})
    return out


@pytest.mark.parametrize("name", ROBOTS)
def test_agrees_with_pytorch_kinematics(name, robot64):
    """The reference: pytorch-kinematics reads the URDF itself; every link, every robot, poses and gradients."""
    pytest.importorskip("pytorch_kinematics")
    from nlo_lab.robot.pk_chain import PKChain

    robot = robot64(name)
    ref = PKChain(robot)
    assert set(ref.joint_names) == set(robot.tree.moving_names)  # mimic joints included, as separate joints
    q = random_q(robot, 8, seed=6)
    ours, theirs = robot.forward_kinematics(q), ref.forward_kinematics(q)
    assert set(theirs) == set(ours)
    for link, T in theirs.items():
        # 1e-6: pytorch-kinematics stores the URDF's numbers in float32 before .to(float64)
        np.testing.assert_allclose(ours[link].numpy(), T.numpy(), atol=1e-6, rtol=0, err_msg=f"{name} {link}")
    links = [robot.arm(s).wrist for s in ("left", "right")] + [robot.arm(s).elbow for s in ("left", "right")]
    w = torch.randn(len(links), 3, dtype=torch.float64, generator=torch.Generator().manual_seed(1))
    grads = []
    for fk in (robot.forward_kinematics, ref.forward_kinematics):
        qq = q.clone().requires_grad_(True)
        poses = fk(qq)
        (torch.stack([poses[k][:, :3, 3] for k in links], 1) * w).sum().backward()
        grads.append(qq.grad)
    torch.testing.assert_close(grads[0], grads[1], atol=1e-5, rtol=0)


def test_pk_chain_angles_expand_the_mimic_joints(robot64):
    pytest.importorskip("pytorch_kinematics")
    from nlo_lab.robot.pk_chain import PKChain

    robot = robot64("yumi")
    ref = PKChain(robot)
    assert len(ref.joint_names) == robot.n_joints + 12  # six coupled joints per Inspire hand
    q = random_q(robot, 3, seed=7)
    theta = ref.angles(q)
    for name, _, _, _, _, src, mult, off in mimic_table(robot):
        k, s = ref.joint_names.index(name), robot.joint_names.index(src)
        torch.testing.assert_close(theta[:, k], mult * q[:, s] + off)
    for i, name in enumerate(robot.joint_names):
        torch.testing.assert_close(theta[:, ref.joint_names.index(name)], q[:, i])


@pytest.mark.parametrize("name", ROBOTS)
def test_agrees_with_yourdfpy(name, robot64):
    robot = robot64(name)
    q = random_q(robot, 6, seed=4)
    ours = robot.forward_kinematics(q)
    for b, ref in enumerate(yourdfpy_poses(robot, q.numpy())):
        for link, T in ref.items():
            np.testing.assert_allclose(ours[link][b].numpy(), T, atol=1e-6, rtol=0, err_msg=f"{name} {link} sample {b}")


def mimic_table(robot: Robot) -> list[tuple[str, str, str, str, np.ndarray, str, float, float]]:
    """Mimic joints read straight from the URDF XML: (joint, parent, child, origin xyz/rpy, axis, source, mult, offset)."""
    out = []
    for el in ET.parse(robot.spec.urdf).getroot().findall("joint"):
        m = el.find("mimic")
        if m is None:
            continue
        o = el.find("origin")
        T = np.eye(4)
        T[:3, :3] = rpy_to_matrix([float(v) for v in o.get("rpy", "0 0 0").split()])
        T[:3, 3] = [float(v) for v in o.get("xyz", "0 0 0").split()]
        axis = np.array([float(v) for v in el.find("axis").get("xyz").split()])
        out.append((el.get("name"), el.find("parent").get("link"), el.find("child").get("link"), T, axis / np.linalg.norm(axis),
                    m.get("joint"), float(m.get("multiplier", 1)), float(m.get("offset", 0))))  # fmt: skip
    return out


def test_coupled_joints_follow_their_ratios(robot64):
    robot = robot64("yumi")
    table = mimic_table(robot)
    assert len(table) == 12, "six coupled joints per Inspire hand"
    q = random_q(robot, 4, seed=5)
    poses = robot.forward_kinematics(q)
    for name, parent, child, origin, axis, src, mult, off in table:
        src_idx = robot.joint_names.index(src) if src in robot.joint_names else None
        assert src_idx is not None, f"{name} mimics {src}, which is not actuated"
        for b in range(q.shape[0]):
            # the child's rotation relative to the joint frame is a rotation about the axis by the joint angle
            T_rel = np.linalg.inv(poses[parent][b].numpy() @ origin) @ poses[child][b].numpy()
            R = T_rel[:3, :3]
            sin = 0.5 * axis @ np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
            cos = 0.5 * (np.trace(R) - 1.0)
            angle = math.atan2(sin, cos)
            assert angle == pytest.approx(mult * float(q[b, src_idx]) + off, abs=1e-9), name
            np.testing.assert_allclose(T_rel[:3, 3], 0.0, atol=1e-12)


def test_wrong_number_of_angles(robot64):
    robot = robot64("nao")
    with pytest.raises(ValueError, match="expected 10 joint angles"):
        robot.forward_kinematics(torch.zeros(2, 9, dtype=torch.float64))


@pytest.mark.parametrize("name", ROBOTS)
def test_pointer_jumping_equals_level_by_level(name, robot64):
    robot = robot64(name)
    q = random_q(robot, 3, seed=5)
    jump = robot.tree.body_poses(q, compose="jumps")
    levels = robot.tree.body_poses(q, compose="levels")
    torch.testing.assert_close(jump, levels, atol=1e-12, rtol=0)


@pytest.mark.parametrize("name", ROBOTS)
def test_link_subsets_and_mapped_points_equal_full_fk(name, robot64):
    robot = robot64(name)
    q = random_q(robot, 4, seed=6)
    T = robot.forward_kinematics_tensor(q)  # (4, L, 4, 4)
    links = torch.tensor([0, len(robot.link_names) - 1, robot.link_index(robot.arm("left").wrist)])
    torch.testing.assert_close(robot.tree.forward_links(q, links), T[:, links], atol=1e-12, rtol=0)
    names = [robot.link_names[int(k)] for k in links]
    vec = np.array([[0.1, -0.2, 0.3, 1.0], [0.0, 0.0, 1.0, 0.0], [0.05, 0.0, 0.0, 1.0]])  # two points, one direction
    body, v = robot.tree.point_map(names, vec)
    got = robot.tree.map_points(q, torch.as_tensor(body), torch.as_tensor(v))  # (4, 3, 3)
    expected = (T[:, links] @ torch.as_tensor(vec)[:, :, None])[..., :3, 0]
    torch.testing.assert_close(got, expected, atol=1e-12, rtol=0)


@pytest.mark.parametrize("name", ROBOTS)
def test_mapped_points_closed_form_gradient_equals_autograd(name, robot64):
    """map_points' written-out gradient (axis x lever arm, mimic joints included) = autograd through the FK."""
    from nlo_lab.objective import point_plan

    robot = robot64(name)
    c = point_plan(robot, torch.float64, "cpu")
    q = random_q(robot, 5, seed=12).requires_grad_(True)
    w = torch.randn(5, len(c.body), 3, generator=torch.Generator().manual_seed(2), dtype=torch.float64)
    fast = robot.tree.map_points(q, c.body, c.vectors, analytic_gradient=True)
    ref = robot.tree.map_points(q, c.body, c.vectors)
    torch.testing.assert_close(fast, ref, atol=1e-14, rtol=0)
    (g_fast,) = torch.autograd.grad((fast * w).sum(), q)
    (g_ref,) = torch.autograd.grad((ref * w).sum(), q)
    torch.testing.assert_close(g_fast, g_ref, atol=1e-12, rtol=1e-12)
    assert torch.autograd.gradcheck(lambda x: robot.tree.map_points(x, c.body, c.vectors, analytic_gradient=True), (q[:2].detach().requires_grad_(True),))
