"""The robot as it looks: a URDF's visual meshes drawn, decimated to a face budget; missing ones stood in for."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
import trimesh

from nlo_lab.robot import load_robot
from nlo_lab.robot.urdf import parse_urdf
from nlo_lab.viz.export import recording_visualizer, scene_commands
from nlo_lab.viz.robot_visuals import MESH_FACE_BUDGET, STAND_IN_RADIUS, robot_visuals_of
from nlo_lab.viz.scene import RobotScene, robot_visuals

ARM = """
  <joint name="{s}_j1" type="revolute"><parent link="torso"/><child link="{s}_upper"/><origin xyz="0 {y} 0.4"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" velocity="2" effort="1"/></joint>
  <link name="{s}_upper"><visual><origin xyz="0 0 -0.1"/><geometry><mesh filename="{upper}"/></geometry></visual></link>
  <joint name="{s}_j2" type="revolute"><parent link="{s}_upper"/><child link="{s}_fore"/><origin xyz="0 0 -0.2"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="0" velocity="2" effort="1"/></joint>
  <link name="{s}_fore"><visual><geometry><cylinder radius="0.03" length="0.2"/></geometry></visual></link>
  <joint name="{s}_j3" type="revolute"><parent link="{s}_fore"/><child link="{s}_hand"/><origin xyz="0 0 -0.2"/>
    <axis xyz="0 0 1"/><limit lower="-2" upper="2" velocity="2" effort="1"/></joint>
  <link name="{s}_hand"><visual><geometry><mesh filename="meshes/gone.stl"/></geometry></visual>
    <collision><geometry><box size="0.05 0.02 0.08"/></geometry></collision></link>
"""


@pytest.fixture
def meshed(tmp_path):
    """A robot whose upper arms are a 20,480-face sphere mesh and whose hands' mesh is missing."""
    (tmp_path / "meshes").mkdir()
    trimesh.creation.icosphere(subdivisions=5, radius=0.05).export(tmp_path / "meshes" / "ball.stl")
    urdf = tmp_path / "meshed.urdf"
    urdf.write_text('<robot name="meshed"><link name="torso"><visual><geometry><box size="0.2 0.3 0.5"/></geometry></visual></link>'
                    + ARM.format(s="l", y=0.2, upper="meshes/ball.stl") + ARM.format(s="r", y=-0.2, upper="package://x/meshes/ball.stl")
                    + "</robot>")
    spec = tmp_path / "meshed.json"
    spec.write_text(json.dumps({"name": "meshed", "urdf": "meshed.urdf", "base_link": "torso",
                                "actuated_joints": [f"{s}_j{k}" for s in "lr" for k in (1, 2, 3)],
                                "arms": {side: {"shoulder": f"{s}_upper", "elbow": f"{s}_fore", "wrist": f"{s}_hand"}
                                         for side, s in (("left", "l"), ("right", "r"))}}))
    return urdf, spec


def test_meshes_are_decimated_to_the_budget_and_missing_ones_stood_in_for(meshed):
    urdf, _ = meshed
    with pytest.warns(UserWarning, match="gone.stl is missing") as caught:
        visuals = robot_visuals_of(parse_urdf(urdf), budget=2000)
    assert len([w for w in caught if "gone.stl" in str(w.message)]) == 2  # one per missing mesh use
    meshes = [v for v in visuals if v.kind == "mesh"]
    assert [v.link for v in meshes] == ["l_upper", "r_upper"]
    for v in meshes:
        assert len(v.faces) <= 1000 + 50 and len(v.faces) > 500  # 20,480 faces shared out: 1,000 each
        assert v.vertices.dtype == np.float32 and v.faces.max() < len(v.vertices)
        # still the ball, at its origin 0.1 m below the joint (the visual's <origin> applied)
        centre = (v.vertices.max(0) + v.vertices.min(0)) / 2
        np.testing.assert_allclose(centre, [0, 0, -0.1], atol=2e-3)
        np.testing.assert_allclose(v.vertices.max(0) - v.vertices.min(0), 0.1, atol=5e-3)
    stand_ins = [v for v in visuals if v.link.endswith("_hand")]
    assert [v.kind for v in stand_ins] == ["box", "box"]  # the hand's collision box stands in for its missing mesh
    assert {v.kind for v in visuals if v.link == "torso"} == {"box"}
    assert MESH_FACE_BUDGET >= 20_000 and STAND_IN_RADIUS > 0


def test_the_scene_draws_the_meshes(meshed):
    _, spec = meshed
    robot = load_robot(spec)
    vis = recording_visualizer()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = RobotScene(vis, robot).draw()
    kinds = [v.kind for v in scene.visuals]
    assert kinds.count("mesh") == 2
    commands = b"".join(scene_commands(vis.window.tree))
    assert commands.count(b"BufferGeometry") >= 2  # meshcat's triangle meshes
    pts = scene.extent_points(robot.reference_q.numpy())
    # the balls (radius 0.05) sit 0.1 m below the shoulders at (0, +-0.2, 0.4): their boxes frame the scene too
    assert pts[:, 2].max() == pytest.approx(0.35, abs=2e-3) and pts[:, 1].max() == pytest.approx(0.25, abs=2e-3)


@pytest.mark.parametrize("name", ["yumi", "nao", "pepper"])
def test_the_bundled_robots_keep_their_primitives(name):
    assert {v.kind for v in robot_visuals(load_robot(name))} <= {"box", "cylinder", "sphere"}
