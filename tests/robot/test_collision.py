"""Segment and capsule distances against brute-force sampling; gradients stay finite."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from nlo_lab.robot.collision import capsule_distance, segment_distance

N = 2001  # samples per segment for the brute-force reference


def brute_force(a0, a1, b0, b1, n=N):
    """Sampled distance and its guaranteed over-estimate bound (half a sample step on each segment)."""
    s = torch.linspace(0, 1, n, dtype=torch.float64)[:, None]
    pa, pb = a0 + s * (a1 - a0), b0 + s * (b1 - b0)  # (N, 3)
    d = torch.cdist(pa, pb).min()
    slack = 0.5 * ((a1 - a0).norm() + (b1 - b0).norm()) / (n - 1)
    return d, slack


def special_cases():
    t = lambda *v: torch.tensor(v, dtype=torch.float64)  # noqa: E731
    return [
        (t(0, 0, 0), t(1, 0, 0), t(0, 1, 0), t(1, 1, 0)),  # parallel, overlapping
        (t(0, 0, 0), t(1, 0, 0), t(2, 1, 0), t(3, 1, 0)),  # parallel, disjoint
        (t(0, 0, 0), t(1, 0, 0), t(3, 0, 0), t(2, 0, 0)),  # collinear, disjoint, reversed
        (t(0, 0, 0), t(1, 0, 0), t(0.5, -1, 0), t(0.5, 1, 0)),  # crossing: distance 0
        (t(0, 0, 0), t(1, 0, 0), t(0.5, 0.2, 0.3), t(0.5, 0.2, 0.3)),  # b is a point
        (t(0.3, 0.3, 0.3), t(0.3, 0.3, 0.3), t(0, 0, 0), t(0, 0, 1)),  # a is a point
        (t(1, 1, 1), t(1, 1, 1), t(0, 0, 0), t(0, 0, 0)),  # two points
        (t(0, 0, 0), t(1, 0, 0), t(-1, 0.1, 0), t(3, 0.1 + 1e-9, 0)),  # almost parallel
    ]


def test_segment_distance_matches_brute_force():
    g = torch.Generator().manual_seed(0)
    cases = special_cases() + [tuple(torch.randn(4, 3, generator=g, dtype=torch.float64) * 0.3)]
    cases += [tuple(torch.randn(4, 3, generator=g, dtype=torch.float64) * 0.3) for _ in range(40)]
    a0, a1, b0, b1 = (torch.stack(x) for x in zip(*cases, strict=True))
    d = segment_distance(a0, a1, b0, b1)  # batched
    for i, case in enumerate(cases):
        ref, slack = brute_force(*case)
        assert float(d[i]) <= float(ref) + 1e-12, f"case {i}: closer than any sampled pair"
        assert float(ref) - float(d[i]) <= float(slack) + 1e-12, f"case {i}: {float(d[i])} vs sampled {float(ref)}"
    # exact values of the special cases
    torch.testing.assert_close(d[:4], torch.tensor([1.0, (1 + 1) ** 0.5, 1.0, 0.0], dtype=torch.float64), atol=1e-6, rtol=0)


def test_segment_distance_is_symmetric_and_broadcasts():
    g = torch.Generator().manual_seed(1)
    a0, a1, b0, b1 = torch.randn(4, 5, 3, generator=g, dtype=torch.float64)
    torch.testing.assert_close(segment_distance(a0, a1, b0, b1), segment_distance(b1, b0, a1, a0))
    assert segment_distance(a0, a1, b0[:1], b1[:1]).shape == (5,)


def test_gradients_finite_for_degenerate_cases():
    for case in special_cases():
        pts = [p.clone().requires_grad_(True) for p in case]
        segment_distance(*pts).backward()
        for p in pts:
            assert torch.isfinite(p.grad).all()
    for case in special_cases():  # float32 too
        pts = [p.float().requires_grad_(True) for p in case]
        segment_distance(*pts).backward()
        assert all(torch.isfinite(p.grad).all() for p in pts)


def test_gradient_matches_finite_differences():
    g = torch.Generator().manual_seed(2)
    pts = tuple(torch.randn(3, 3, generator=g, dtype=torch.float64).requires_grad_(True) for _ in range(4))
    assert torch.autograd.gradcheck(segment_distance, pts, eps=1e-6, atol=1e-6)


def test_capsule_distance_subtracts_radii():
    a0, a1 = torch.tensor([0.0, 0, 0]), torch.tensor([1.0, 0, 0])
    b0, b1 = torch.tensor([0.0, 1, 0]), torch.tensor([1.0, 1, 0])
    assert float(capsule_distance(a0, a1, 0.2, b0, b1, 0.3)) == pytest.approx(0.5)
    assert float(capsule_distance(a0, a1, 0.7, b0, b1, 0.6)) == pytest.approx(-0.3)


@pytest.mark.parametrize("name", ["yumi", "nao", "pepper"])
def test_robot_capsule_distances_match_brute_force(name, robot64):
    robot = robot64(name)
    g = torch.Generator().manual_seed(3)
    q = robot.lower_limits + torch.rand(3, robot.n_joints, generator=g, dtype=torch.float64) * (robot.upper_limits - robot.lower_limits)
    poses = robot.forward_kinematics(q)
    d = robot.capsule_distances(poses)  # (3, P)
    torch.testing.assert_close(d, robot.capsule_distances(robot.forward_kinematics_tensor(q)))
    caps = {c.name: c for c in robot.spec.capsules}
    for b in range(q.shape[0]):
        for p, (na, nb) in enumerate(robot.spec.collision_pairs):
            ends = []
            for c in (caps[na], caps[nb]):
                T = poses[c.link][b]
                for pt in (c.p0, c.p1):
                    ends.append(T[:3, :3] @ torch.tensor(pt, dtype=torch.float64) + T[:3, 3])
            ref, slack = brute_force(*ends, n=301)  # capsules <= 0.3 m: slack <= 1 mm
            ref = ref - caps[na].radius - caps[nb].radius
            assert float(ref) - float(slack) - 1e-12 <= float(d[b, p]) <= float(ref) + 1e-12, (name, na, nb)


def test_numpy_and_torch_closed_forms_agree():
    """The CPU path runs the closed form in numpy; other devices run the same code in torch."""
    import numpy as np

    from nlo_lab.robot.collision import segment_closest_points

    g = torch.Generator().manual_seed(11)
    ends = torch.randn(200, 4, 3, generator=g, dtype=torch.float64)
    ends[:20, 1] = ends[:20, 0]  # a is a point
    ends[20:40, 3] = ends[20:40, 2] + 1e-9  # b is (almost) a point
    ends[40:60, 2:] = ends[40:60, :2] + torch.tensor([0.0, 0.3, 0.0], dtype=torch.float64)  # parallel
    E = ends.permute(1, 2, 0)  # (4, 3, n)
    ours = segment_closest_points(E.numpy())
    ref = segment_closest_points(E)
    for a, b in zip(ours, ref, strict=True):
        torch.testing.assert_close(torch.from_numpy(np.ascontiguousarray(a)), b, atol=1e-12, rtol=0)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["yumi", "nao", "pepper"])
def test_robot_capsule_distances_agree_with_trimesh_meshes(name, robot64):
    """An independent check with trimesh: each capsule a triangle mesh; gaps and overlaps measured between meshes.

    Points sampled evenly on one mesh, their distance to the other mesh's surface (signed
    inside it): the smallest gap, or the deepest point, is the capsule distance. The
    meshes are inscribed (24-gons: at most 0.9 % of the radius smaller) and the points
    about 1 cm apart on the larger mesh, closer on a thin one (each mesh's points against the other, the
    smaller gap), so the two agree to 3 mm. Checked on the pairs closest to contact.
    """
    trimesh = pytest.importorskip("trimesh")
    pytest.importorskip("rtree")  # trimesh's closest-point queries need it
    robot = robot64(name)
    g = torch.Generator().manual_seed(11)
    q = robot.lower_limits + torch.rand(64, robot.n_joints, generator=g, dtype=torch.float64) * (robot.upper_limits - robot.lower_limits)
    poses = robot.forward_kinematics(q)
    d = robot.capsule_distances(poses).numpy()  # (64, P)
    caps = {c.name: c for c in robot.spec.capsules}

    def mesh(c, T):
        p0, p1 = (T[:3, :3] @ np.array(x) + T[:3, 3] for x in (c.p0, c.p1))
        axis = p1 - p0
        length = float(np.linalg.norm(axis))
        m = trimesh.creation.capsule(height=length, radius=c.radius, count=[24, 24])  # along z, centred
        if length > 1e-9:
            m.apply_transform(trimesh.geometry.align_vectors([0.0, 0.0, 1.0], axis / length))
        m.apply_translation((p0 + p1) / 2)
        return m

    # Overlaps are measured as the deepest surface point inside the other capsule; that equals
    # -distance only while neither axis reaches into the other's radius (depth well below the smaller radius).
    smaller = np.array([min(caps[a].radius, caps[b].radius) for a, b in robot.spec.collision_pairs])
    cases = [(b, p) for b in range(d.shape[0]) for p in range(d.shape[1]) if 2e-3 < abs(d[b, p]) and -d[b, p] < 0.5 * smaller[p]]
    apart = sorted((c for c in cases if d[c] > 0), key=lambda c: d[c])[:4]
    overlap = sorted((c for c in cases if d[c] < 0), key=lambda c: -d[c])[:4]
    assert apart and overlap, "random poses give both cases"
    for b, p in apart + overlap:
        na, nb = robot.spec.collision_pairs[p]
        A, B = (mesh(caps[n], poses[caps[n].link][b].numpy()) for n in (na, nb))
        points = trimesh.sample.sample_surface_even(A, 800, seed=0)[0]
        other = trimesh.sample.sample_surface_even(B, 800, seed=0)[0]
        if d[b, p] > 0:  # both ways: a big capsule's points lie too far apart to find a thin one's nearest
            measured = min(float(trimesh.proximity.closest_point(B, points)[1].min()),
                           float(trimesh.proximity.closest_point(A, other)[1].min()))
        else:  # signed_distance is > 0 inside B
            measured = -max(float(trimesh.proximity.signed_distance(B, points).max()), float(trimesh.proximity.signed_distance(A, other).max()))
        assert measured == pytest.approx(d[b, p], abs=3e-3), (name, na, nb, b)
