"""Tests of nlo_lab.viz: scenes, static export, the notebook widget (no server, no port), plots."""

from __future__ import annotations

import base64
import os
import re
import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest
import umsgpack

from nlo_lab.errors import NloLabError
from nlo_lab.human import Demonstration
from nlo_lab.robot import load_robot
from nlo_lab.viz import (
    GROUP_COLOURS,
    RetargetScene,
    export_html,
    link_groups,
    plot_convergence,
    plot_joint_trajectories,
    plot_loss_terms,
    recording_visualizer,
    robot_visuals,
    static_html,
)
from nlo_lab.viz.scene import matrix_to_quaternion
from nlo_lab.viz.widget import pack_commands, unpack_commands

ROBOTS = ("nao", "pepper", "yumi")
ALLOWED_URLS = {"http://www.w3.org/1999/xhtml"}  # an XML namespace name inside three.js, never fetched


# ------------------------------------------------------------------ helpers
def commands_of(page: str) -> list[dict]:
    """Decode every meshcat command embedded in a static page."""
    blobs = re.findall(r'data:application/octet-binary;base64,([A-Za-z0-9+/=]+)', page)
    return [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]


def sweep(robot, T=12):
    lo, hi = robot.lower_limits.double().numpy(), robot.upper_limits.double().numpy()
    s = 0.5 + 0.3 * np.sin(np.linspace(0, 2 * np.pi, T))[:, None]
    return lo + (hi - lo) * s  # (T, n) inside the limits


def synthetic_demo(T=12, seed=0):
    rng = np.random.default_rng(seed)
    arm = np.zeros((T, 2, 3, 3))
    arm[:, 0, 0], arm[:, 1, 0] = [0, 0.18, 0], [0, -0.18, 0]
    for s in range(2):
        arm[:, s, 1] = arm[:, s, 0] + [0.05, 0.0, -0.28] + np.cumsum(rng.normal(scale=0.003, size=(T, 3)), 0)
        arm[:, s, 2] = arm[:, s, 1] + [0.25, 0.0, 0.05] + np.cumsum(rng.normal(scale=0.003, size=(T, 3)), 0)
    fingers = np.zeros((T, 2, 5, 2, 3))
    for f in range(5):
        fingers[:, :, f, 0] = arm[:, :, 2] + [0.08, 0.02 * (f - 2), 0]
        fingers[:, :, f, 1] = arm[:, :, 2] + [0.15, 0.02 * (f - 2), 0]
    rot = np.broadcast_to(np.eye(3), (T, 2, 3, 3)).copy()
    mask = np.ones((T, 2, 3), bool)
    mask[3, 1, 2] = False  # one unseen right wrist
    return Demonstration(25.0, arm, mask, rot, np.ones((T, 2), bool), fingers, np.ones((T, 2, 5), bool), name="synthetic")


@pytest.fixture(scope="module", params=ROBOTS)
def robot(request):
    return load_robot(request.param)


# ------------------------------------------------------------------ scenes
def test_quaternion_matches_meshcat():
    from meshcat.animation import js_quaternion

    rng = np.random.default_rng(0)
    for _ in range(50):
        A, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        A *= np.sign(np.linalg.det(A))
        T = np.eye(4)
        T[:3, :3] = A
        q_ref = np.array(js_quaternion(T))  # (x, y, z, w)
        q = matrix_to_quaternion(A)
        assert min(np.abs(q - q_ref).max(), np.abs(q + q_ref).max()) < 1e-12
    # 180° turns are the hard case for the trace formula
    for R in (np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]), np.diag([-1.0, -1, 1])):
        q = matrix_to_quaternion(R)
        assert np.linalg.norm(q) == pytest.approx(1.0) and abs(q[3]) < 1e-12


def test_tiny_urdf_visuals_and_groups(tmp_path):
    urdf = tmp_path / "tiny.urdf"
    urdf.write_text(textwrap.dedent("""\
        <?xml version="1.0"?>
        <robot name="tiny">
          <link name="base"><visual><geometry><box size="0.2 0.3 0.4"/></geometry></visual></link>
          <link name="upper_arm"><visual><origin xyz="0 0 -0.1"/><geometry><cylinder radius="0.04" length="0.2"/></geometry></visual></link>
          <link name="wrist"/>
          <link name="finger"><visual><geometry><sphere radius="0.02"/></geometry></visual></link>
          <link name="head"><visual><geometry><mesh filename="head.stl"/></geometry></visual></link>
          <joint name="j1" type="revolute"><parent link="base"/><child link="upper_arm"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
          <joint name="j2" type="fixed"><parent link="upper_arm"/><child link="wrist"/></joint>
          <joint name="j3" type="fixed"><parent link="wrist"/><child link="finger"/></joint>
          <joint name="j4" type="fixed"><parent link="base"/><child link="head"/></joint>
        </robot>"""))
    with pytest.warns(UserWarning, match="head.stl is missing"):
        visuals = robot_visuals(urdf)
    # the missing mesh: a warning and a stand-in (nlo_lab.viz.robot_visuals)
    assert [(v.link, v.kind) for v in visuals] == [("base", "box"), ("upper_arm", "cylinder"), ("finger", "sphere"), ("head", "sphere")]
    assert visuals[0].size == (0.2, 0.3, 0.4)
    assert visuals[1].size == (0.04, 0.2) and visuals[1].T_link_visual[2, 3] == pytest.approx(-0.1)
    by_role = link_groups(urdf, {"left": ("upper_arm", "wrist")})
    assert by_role == {"base": "torso", "upper_arm": "arm", "wrist": "arm", "finger": "hand", "head": "head"}


def test_every_robot_visual_is_drawn_with_its_group_colour(robot):
    page = static_html(robot, sweep(robot, T=1))
    cmds = commands_of(page)
    objects = {c["path"]: c for c in cmds if c["type"] == "set_object"}
    visuals = robot_visuals(robot)
    assert len(visuals) > 5
    groups = link_groups(robot, {s: (robot.arm(s).shoulder, robot.arm(s).wrist) for s in ("left", "right")})
    for i, v in enumerate(visuals):
        cmd = objects[f"/meshcat/robot/{v.link}/v{i}"]
        geom = cmd["object"]["geometries"][0]
        assert geom["type"] == {"box": "BoxGeometry", "cylinder": "CylinderGeometry", "sphere": "SphereGeometry"}[v.kind]
        assert cmd["object"]["materials"][0]["color"] == GROUP_COLOURS[groups[v.link]]
    used = {groups[v.link] for v in visuals}
    assert {"arm", "torso"} <= used
    if robot.has_fingers:
        assert "hand" in used
    # every wrist is in the arm group
    for side in ("left", "right"):
        assert groups[robot.arm(side).wrist] == "arm"


def test_set_frame_moves_the_robot_to_its_fk(robot):
    import torch

    vis = recording_visualizer()
    q = sweep(robot, T=6)
    scene = RetargetScene(vis, robot, q)
    tree = vis.window.tree
    wrist = robot.arm("left").wrist
    link = wrist if wrist in scene.robot_scene.links else scene.robot_scene.links[-1]
    node = tree["meshcat"]["robot"][link]

    def shown_position():
        return np.array(umsgpack.unpackb(node.transform)["matrix"], dtype=np.float64).reshape(4, 4).T[:3, 3]

    for t in (0, 3):
        scene.set_frame(t)
        fk = robot.forward_kinematics(torch.as_tensor(q[t:t + 1], dtype=robot.lower_limits.dtype))[link][0, :3, 3]
        np.testing.assert_allclose(shown_position(), fk.double().numpy(), atol=1e-6)
    with pytest.raises(NloLabError, match="frame 6"):
        scene.set_frame(6)


def _clips(page: str) -> dict[str, dict]:
    return {a["path"]: a["clip"] for c in commands_of(page) if c["type"] == "set_animation" for a in c["animations"]}


def _track(clip: dict, name: str) -> list:
    return [k["value"] for k in next(t for t in clip["tracks"] if t["name"] == "." + name)["keys"]]


def test_export_html_is_self_contained_and_animated(tmp_path, robot):
    q = sweep(robot, T=12)
    demo = synthetic_demo(T=12)
    path = export_html(tmp_path / "viewer.html", robot, q, demo=demo, offset=0.9, human_scale="human")
    page = path.read_text(encoding="utf-8")
    assert [p.name for p in tmp_path.iterdir()] == ["viewer.html"]  # no temporary left
    urls = set(re.findall(r"https?://[^\s\"'<>)\\]*", page))
    assert urls <= ALLOWED_URLS, urls - ALLOWED_URLS
    assert not re.search(r"""(src|href)\s*=\s*["'](?!data:)""", page.split("<script>")[0])  # nothing loaded in the head
    cmds = commands_of(page)
    paths = {c["path"] for c in cmds if c["type"] == "set_object"}
    assert any(p.startswith("/meshcat/robot/") for p in paths)
    assert {"/meshcat/human/points/left_wrist", "/meshcat/human/bones/right_fore", "/meshcat/human/body/torso", "/meshcat/human/body/head"} <= paths
    anims = [c for c in cmds if c["type"] == "set_animation"]
    assert len(anims) == 1
    clips = _clips(page)
    assert all(c["fps"] == 25.0 for c in clips.values())
    pos = _track(clips["/meshcat/human/points/left_wrist"], "position")
    assert len(pos) == 12
    # side by side, as recorded: the human is shifted 0.9 m along -Y
    np.testing.assert_allclose(pos[5], demo.arm_positions[5, 0, 2] + [0, -0.9, 0], atol=1e-12)
    # the unseen right wrist holds its last valid position and is hidden in that frame only
    right = clips["/meshcat/human/points/right_wrist"]
    rpos = _track(right, "position")
    assert rpos[3] == rpos[2]
    assert _track(right, "visible") == [t != 3 for t in range(12)]
    assert _track(clips["/meshcat/human/bones/right_fore"], "visible")[3] is False
    assert "visible" not in {t["name"][1:] for t in clips["/meshcat/human/points/left_wrist"]["tracks"]}  # always seen: no track


def test_side_by_side_human_at_robot_scale():
    from nlo_lab.human import map_to_robot

    robot = load_robot("nao")
    demo = synthetic_demo(T=6)
    page = static_html(robot, sweep(robot, T=6), demo=demo, offset=0.5)  # human_scale="robot" is the default
    clips = _clips(page)
    mapped = map_to_robot(demo, robot)  # (T, 2, 3, 3)
    shift = np.array([0.0, -0.5, 0.0])
    for s, side in enumerate(("left", "right")):
        for j, joint in enumerate(("shoulder", "elbow")):
            np.testing.assert_allclose(_track(clips[f"/meshcat/human/points/{side}_{joint}"], "position")[4], mapped[4, s, j] + shift, atol=1e-9)
        # the hand: the same per-arm factor as the metric's mapping, about the mapped wrist
        upper, fore = robot.zero_pose_lengths(side)
        k = (float(upper) + float(fore)) / sum(demo.arm_lengths(side))
        assert k < 0.6  # NAO's arm is much shorter than the human's: the test would see a wrong factor
        wrist = mapped[4, s, 2] + shift
        tip = np.array(_track(clips[f"/meshcat/human/points/{side}_f2_tip"], "position")[4])
        raw = demo.finger_positions[4, s, 2, 1] - demo.arm_positions[4, s, 2]
        np.testing.assert_allclose(tip - wrist, k * raw, atol=1e-9)
    # the head is drawn at the same scale: its radius shrinks with the mean factor
    objects = {c["path"]: c for c in commands_of(page) if c["type"] == "set_object"}
    r_robot = objects["/meshcat/human/body/head"]["object"]["geometries"][0]["radius"]
    r_human = {c["path"]: c for c in commands_of(static_html(robot, sweep(robot, T=6), demo=demo, human_scale="human")) if c["type"] == "set_object"}[
        "/meshcat/human/body/head"]["object"]["geometries"][0]["radius"]
    ks = [(sum(float(v) for v in robot.zero_pose_lengths(sd))) / sum(demo.arm_lengths(sd)) for sd in ("left", "right")]
    assert r_robot == pytest.approx(r_human * np.mean(ks), rel=1e-6)


def test_auto_offset_puts_the_human_beside_the_robot(robot):
    from nlo_lab.viz.scene import RobotScene

    demo = synthetic_demo(T=5)
    q = sweep(robot, T=5)
    scene = RetargetScene(recording_visualizer(), robot, q, demo=demo)
    robot_pts = RobotScene(recording_visualizer(), robot).extent_points(q)
    human_pts = scene.human_scene.extent_points()
    gap = robot_pts[:, 1].min() - human_pts[:, 1].max()  # the human is on the robot's right (-Y)
    height = np.ptp(np.concatenate([robot_pts, human_pts])[:, 2])
    assert 0.1 * height < gap < 0.5 * height


def test_camera_frames_the_whole_scene(robot):
    """Every drawn point over the trajectory is in view, and the scene fills most of the view's binding dimension."""
    from nlo_lab.viz.scene import RobotScene

    demo = synthetic_demo(T=8)
    q = sweep(robot, T=8)
    for layout in ("side", "overlay"):
        vis = recording_visualizer()
        scene = RetargetScene(vis, robot, q, demo=demo, layout=layout)
        pts = np.concatenate([RobotScene(recording_visualizer(), robot).extent_points(q), scene.human_scene.extent_points()])
        xy = scene.camera.project(pts)  # (N, 2) in [-1, 1] when in view
        assert np.abs(xy).max() <= 1.0, f"{layout}: part of the scene is out of view"
        assert np.abs(xy).max() > 0.75, f"{layout}: the scene fills only {np.abs(xy).max():.0%} of the view"
        cam, target = np.array(scene.camera.position), np.array(scene.camera.target)
        look = cam - target
        assert look[0] > 0 and look[2] > 0 and abs(look[1]) > 0.1 * np.linalg.norm(look), "not from the front, above and the side"
        # what the viewer receives: content shifted so that the target is the origin meshcat aims at; camera at the offset
        tree = vis.window.tree
        root = np.array(umsgpack.unpackb(tree["meshcat"].transform)["matrix"]).reshape(4, 4).T
        np.testing.assert_allclose(root[:3, 3], -target, atol=1e-12)
        props = [umsgpack.unpackb(p) for p in tree["Cameras"]["default"]["rotated"]["<object>"].properties]
        position = [p["value"] for p in props if p["property"] == "position"][-1]
        np.testing.assert_allclose(position, [look[0], look[2], -look[1]], atol=1e-12)  # Z-up -> three.js Y-up


def test_robot_alone_is_framed_and_small_robots_come_closer():
    distances = {}
    for name in ROBOTS:
        robot = load_robot(name)
        scene = RetargetScene(recording_visualizer(), robot, sweep(robot, T=4))
        distances[name] = np.linalg.norm(np.subtract(scene.camera.position, scene.camera.target))
    assert distances["nao"] < distances["pepper"]  # 0.57 m vs 1.2 m tall


def test_frame_points_rejects_bad_input():
    from nlo_lab.viz import frame_points

    with pytest.raises(NloLabError, match="finite"):
        frame_points(np.full((3, 3), np.nan))
    with pytest.raises(NloLabError, match="elevation"):
        frame_points(np.zeros((2, 3)), elevation=90)
    with pytest.raises(NloLabError, match="fill"):
        frame_points(np.eye(3), fill=2.0)


def test_hidden_points_and_read_only_angles(monkeypatch):
    import torch

    real_as_tensor = torch.as_tensor

    def strict_as_tensor(x, *args, **kwargs):  # torch warns on read-only arrays, but only once per process
        assert not (isinstance(x, np.ndarray) and not x.flags.writeable), "a read-only array went to torch.as_tensor"
        return real_as_tensor(x, *args, **kwargs)

    monkeypatch.setattr(torch, "as_tensor", strict_as_tensor)
    robot = load_robot("nao")
    demo = synthetic_demo(T=4)
    demo.finger_mask[:, 0, 1] = False  # a finger never seen
    q = sweep(robot, T=4)
    q.setflags(write=False)  # as RobotTrajectory.angles
    vis = recording_visualizer()
    scene = RetargetScene(vis, robot, q, demo=demo, human_scale="human")
    scene.set_angles(q[2], t=1)  # the scene keeps its own writable copy
    scene.robot_scene.link_poses(q)
    node = vis.window.tree["meshcat"]["human"]["points"]["left_f1_tip"]
    assert [umsgpack.unpackb(p)["value"] for p in node.properties if umsgpack.unpackb(p)["property"] == "visible"] == [False]
    assert "/meshcat/human/points/left_f1_tip" not in {c["path"] for c in scene.animation().lower()}  # never animated
    wrist = vis.window.tree["meshcat"]["human"]["points"]["right_wrist"]

    def wrist_visible():
        return [umsgpack.unpackb(p)["value"] for p in wrist.properties if umsgpack.unpackb(p)["property"] == "visible"][-1]

    scene.set_frame(3)  # the right wrist is masked in frame 3
    assert wrist_visible() is False
    scene.set_frame(2)
    assert wrist_visible() is True


def test_overlay_places_human_at_robot_shoulders():
    from nlo_lab.human import map_to_robot

    robot = load_robot("nao")
    demo = synthetic_demo(T=5)
    page = static_html(robot, sweep(robot, T=5), demo=demo, layout="overlay")
    clips = {a["path"]: a["clip"] for c in commands_of(page) if c["type"] == "set_animation" for a in c["animations"]}
    pos = next(t for t in clips["/meshcat/human/points/left_shoulder"]["tracks"] if t["name"] == ".position")
    np.testing.assert_allclose(pos["keys"][0]["value"], map_to_robot(demo, robot)[0, 0, 0], atol=1e-9)
    np.testing.assert_allclose(pos["keys"][0]["value"], robot.shoulder_position("left").double().numpy(), atol=1e-6)


def test_bad_scene_input():
    robot = load_robot("nao")
    with pytest.raises(NloLabError, match="layout"):
        static_html(robot, sweep(robot, 3), layout="stacked")
    with pytest.raises(NloLabError, match="frames"):
        static_html(robot, sweep(robot, 3), demo=synthetic_demo(T=4))
    with pytest.raises(NloLabError, match=r"\(T, 10\)"):
        static_html(robot, np.zeros((3, 4)))
    with pytest.raises(NloLabError, match="does not exist"):
        export_html("/nonexistent-folder/x.html", robot, sweep(robot, 3))
    with pytest.raises(NloLabError, match="human_scale"):
        static_html(robot, sweep(robot, 4), demo=synthetic_demo(T=4), human_scale="giant")
    with pytest.raises(NloLabError, match="overlay"):
        static_html(robot, sweep(robot, 4), demo=synthetic_demo(T=4), layout="overlay", human_scale="human")


# ------------------------------------------------------------------ the widget
def test_packed_commands_unpack_to_what_was_packed():
    commands = [{"type": "set_transform", "path": "/meshcat/a", "matrix": [float(i) for i in range(16)]},
                {"type": "delete", "path": "/meshcat"}]
    data = pack_commands([umsgpack.packb(c) for c in commands])
    assert unpack_commands(data) == commands
    with pytest.raises(NloLabError, match="past the end"):
        unpack_commands(data[:-1])


class _Sent:
    """Records what a SceneWidget sends to the page."""

    def __init__(self, widget):
        self.messages = []
        widget.send = lambda content, buffers=None: self.messages.append((content, [bytes(b) for b in (buffers or [])]))


def test_scene_widget_sends_meshcat_commands_and_only_what_changed():
    from nlo_lab.viz import RobotScene, SceneWidget

    robot = load_robot("nao")
    widget = SceneWidget(height=300)
    sent = _Sent(widget)
    with widget.hold():
        scene = RobotScene(widget.vis, robot).draw()
        scene.set_pose(robot.neutral_q.numpy())
    assert len(sent.messages) == 1, "one update, one message"
    content, (data,) = sent.messages[0]
    cmds = unpack_commands(data)
    assert content == {"type": "commands", "version": widget._version, "count": len(cmds)}
    assert {c["type"] for c in cmds} == {"set_object", "set_transform"}
    # the same pose again sends nothing; one joint sends only the links below it
    with widget.hold():
        scene.set_pose(robot.neutral_q.numpy())
    assert len(sent.messages) == 1
    q = robot.neutral_q.numpy().copy()
    j = robot.joint_names.index("LElbowRoll")
    q[j] = robot.lower_limits[j].item()
    with widget.hold():
        scene.set_pose(q)
    moved = unpack_commands(sent.messages[-1][1][0])
    assert moved and {c["type"] for c in moved} == {"set_transform"}
    assert all("/robot/l_" in c["path"] or "/robot/L" in c["path"] for c in moved), [c["path"] for c in moved]
    assert len(moved) < len(scene.links) / 2
    # without hold(), every command is a message of its own
    widget.vis["extra"].set_transform(np.eye(4))
    assert len(sent.messages) == 3


def test_scene_widget_gives_a_new_view_the_whole_scene():
    from nlo_lab.viz import SceneWidget

    robot = load_robot("nao")
    widget = SceneWidget()
    sent = _Sent(widget)
    RetargetScene(widget.vis, robot, sweep(robot, 3))
    snapshot = unpack_commands(widget.snapshot())
    assert snapshot[0] == {"type": "delete", "path": "/meshcat"}  # a view that already drew something starts over
    assert {"set_object", "set_transform", "set_property"} <= {c["type"] for c in snapshot}
    assert snapshot[1:] == commands_of(widget.vis.static_html())  # the same scene as the static page
    # display stores the scene in the widget's state (what a saved notebook shows without a kernel)
    assert widget._scene == b""
    widget._repr_mimebundle_()
    assert widget._scene == widget.snapshot() and widget._scene_version == widget._version
    # a view that is up to date gets "current"; one that is behind gets the scene
    widget._on_page_message(widget, {"type": "ready", "view": "a", "version": widget._version}, [])
    assert sent.messages[-1] == ({"type": "current", "view": "a", "version": widget._version}, [])
    widget._on_page_message(widget, {"type": "ready", "view": "b", "version": -1}, [])
    content, (data,) = sent.messages[-1]
    assert content["type"] == "scene" and content["view"] == "b" and data == widget.snapshot()


def test_a_view_that_repeats_ready_gets_the_scene_once():
    from nlo_lab.viz import SceneWidget

    robot = load_robot("nao")
    widget = SceneWidget()
    sent = _Sent(widget)
    RetargetScene(widget.vis, robot, sweep(robot, 3))
    # a view asks again until answered; the repeats that waited behind a busy kernel arrive after the answer
    for _ in range(3):
        widget._on_page_message(widget, {"type": "ready", "view": "v", "version": -1}, [])
    kinds = [content["type"] for content, _ in sent.messages[-3:]]
    assert kinds == ["scene", "current", "current"], kinds
    assert all(content["version"] == widget._version for content, _ in sent.messages[-3:])
    # another view of the same widget gets the scene too
    widget._on_page_message(widget, {"type": "ready", "view": "w", "version": -1}, [])
    assert sent.messages[-1][0]["type"] == "scene"


def test_a_widget_inside_a_container_keeps_its_scene_after_every_cell():
    import ipywidgets

    from nlo_lab.viz import SceneWidget
    from nlo_lab.viz.widget import sync_all

    robot = load_robot("nao")
    inner, shown = SceneWidget(), SceneWidget()
    box = ipywidgets.VBox([inner])  # displaying the box never calls the inner widget's _repr_mimebundle_
    box._repr_mimebundle_()
    RetargetScene(inner.vis, robot, sweep(robot, 3))
    RetargetScene(shown.vis, robot, sweep(robot, 3))
    shown._repr_mimebundle_()
    version = shown._scene_version
    assert inner._scene == b"", "nothing stored yet: a view of the box would have nothing to draw"
    sync_all()  # what IPython runs after every cell (post_run_cell)
    assert inner._scene == inner.snapshot() and inner._scene_version == inner._version > 0
    assert shown._scene_version == version, "an unchanged scene is not stored again"
    inner.vis["robot"].set_transform(np.eye(4))
    sync_all()
    assert inner._scene_version == inner._version and inner._scene == inner.snapshot()
    inner.close()
    sync_all()  # a closed widget is skipped


def test_scene_widgets_sync_after_every_cell_of_an_ipython_kernel():
    from IPython.core.interactiveshell import InteractiveShell

    from nlo_lab.viz import SceneWidget
    from nlo_lab.viz.widget import sync_all

    shell = InteractiveShell.instance()
    try:
        SceneWidget()
        assert sync_all in shell.events.callbacks["post_run_cell"]
        SceneWidget()
        assert shell.events.callbacks["post_run_cell"].count(sync_all) == 1, "registered once per kernel"
    finally:
        InteractiveShell.clear_instance()


def _triangles(geometry: dict) -> int:
    """Triangles three.js makes of a meshcat primitive (a box: 12)."""
    if geometry["type"] == "SphereGeometry":
        return 2 * geometry["widthSegments"] * (geometry["heightSegments"] - 1)
    if geometry["type"] == "CylinderGeometry":
        return 4 * geometry["radialSegments"]  # side (2 per segment) and two caps
    return 12


def test_the_light_detail_draws_the_same_scene_with_fewer_triangles():
    from nlo_lab.viz import SceneWidget
    from nlo_lab.viz.tracks import SEGMENTS

    robot = load_robot("yumi")
    demo = synthetic_demo(T=6)
    scenes = {}
    for detail in ("full", "light"):
        widget = SceneWidget(detail=detail)
        RetargetScene(widget.vis, robot, sweep(robot, 6), demo=demo)
        scenes[detail] = unpack_commands(widget.snapshot())
    full, light = scenes["full"], scenes["light"]
    assert [c["path"] for c in full] == [c["path"] for c in light], "the same nodes"
    geometry = {"full": [], "light": []}
    for a, b in zip(full, light, strict=True):
        if a["type"] != "set_object" or "geometries" not in a["object"]:
            assert a == b, "transforms, properties and animations are the same"
            continue
        ga, gb = a["object"]["geometries"][0], b["object"]["geometries"][0]
        shape = {k: v for k, v in ga.items() if "Segments" not in k and k != "uuid"}
        assert shape == {k: v for k, v in gb.items() if "Segments" not in k and k != "uuid"}, "sizes are the same"
        assert a["object"]["materials"][0]["color"] == b["object"]["materials"][0]["color"]
        geometry["full"].append(_triangles(ga))
        geometry["light"].append(_triangles(gb))
    assert sum(geometry["full"]) > 40_000  # YuMi with its hands and the human: meshcat's own tessellation
    assert sum(geometry["light"]) < sum(geometry["full"]) / 4, (sum(geometry["light"]), sum(geometry["full"]))
    assert SEGMENTS["full"] == (20, 20, 50)  # meshcat's own (meshcat.geometry.Sphere, Cylinder)
    assert SceneWidget().detail == SceneWidget.default_detail == "light"  # the live view's default
    with pytest.raises(NloLabError, match="detail"):
        SceneWidget(detail="coarse")
    # the page decides multisampling unless told (None); a wrong value is named
    assert SceneWidget().antialias is None and SceneWidget(antialias=True).antialias is True
    with pytest.raises(NloLabError, match="antialias"):
        SceneWidget(antialias="on")
    # the static page keeps meshcat's tessellation
    vis = recording_visualizer()
    RetargetScene(vis, robot, sweep(robot, 6), demo=demo)
    static = [_triangles(c["object"]["geometries"][0]) for c in commands_of(vis.static_html())
              if c["type"] == "set_object" and "geometries" in c["object"]]
    assert static == geometry["full"]


def test_the_bundle_travels_once_per_kernel():
    from meshcat.servers.zmqserver import VIEWER_ROOT

    from nlo_lab.viz import SceneWidget

    a, b = SceneWidget(), SceneWidget()
    assert a._bundle is b._bundle
    assert a._bundle.code == (Path(VIEWER_ROOT) / "main.min.js").read_text(encoding="utf-8")
    state = a.get_state()
    assert state["_bundle"] == f"IPY_MODEL_{a._bundle.model_id}"  # a reference, not the 0.85 MB bundle
    assert len(str({k: v for k, v in state.items() if k != "_esm"})) < 10_000
    js = Path(__file__).resolve().parents[2] / "nlo_lab" / "viz" / "scene_widget.js"
    assert a._esm == js.read_text(encoding="utf-8")
    a._bundle.close()
    assert SceneWidget()._bundle is not a._bundle  # a closed bundle (kernel restart of the widgets) is made anew


def _listening_inodes() -> set[str]:
    found = set()
    for name in ("tcp", "tcp6"):
        table = Path("/proc/net") / name
        if table.exists():
            for line in table.read_text().splitlines()[1:]:
                fields = line.split()
                if fields[3] == "0A":  # LISTEN
                    found.add(fields[9])
    return found


def _own_sockets() -> set[str]:
    out = set()
    for fd in Path("/proc/self/fd").iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            out.add(target[8:-1])
    return out


@pytest.mark.skipif(not Path("/proc/net/tcp").exists(), reason="needs Linux /proc to inspect sockets")
def test_views_listen_on_no_port_and_start_no_process():
    from nlo_lab.lab import JointPanel, show_view

    children = Path(f"/proc/{os.getpid()}/task/{os.getpid()}/children")
    before = children.read_text() if children.exists() else ""
    robot = load_robot("nao")
    views = [show_view(robot, sweep(robot, 4)), JointPanel(robot)]
    assert not (_own_sockets() & _listening_inodes()), "a view opened a listening socket"
    if children.exists():
        assert children.read_text() == before, "a view started a process"
    assert views


# ------------------------------------------------------------------ plots
def test_plots():
    import matplotlib.pyplot as plt

    fig, ax = plot_convergence({"encoder": np.geomspace(10, 1, 20), "random": np.geomspace(20, 2, 20)})
    assert len(ax.lines) == 2 and ax.get_yscale() == "log"
    q = np.zeros((30, 3))
    q[10, 1] = 2.0  # above the limit
    fig2, axes = plot_joint_trajectories(q, ["a", "b", "c"], lower=-np.ones(3), upper=np.ones(3), fps=10)
    assert len(axes.flat[1].lines) == 4  # angle, two limits, the violation marks
    assert len(axes.flat[0].lines) == 3
    fig3, ax3 = plot_loss_terms({"ee": np.array([1.0, 3.0]), "ori": 0.5}, weights={"ee": 2.0})
    assert [p.get_height() for p in ax3.patches] == [4.0, 0.5]
    with pytest.raises(NloLabError):
        plot_joint_trajectories(q, ["a", "b"])
    plt.close("all")


# ----------------------------------------------------------------------------- the output's own time base
def _key_seconds(clip: dict) -> list[np.ndarray]:
    """Each track's key times in seconds, as the page plays them (key time / clip fps)."""
    return [np.array([k["time"] for k in t["keys"]]) / clip["fps"] for t in clip["tracks"]]


def test_viewer_plays_the_retimed_time_base(tmp_path, robot):
    q = sweep(robot, T=12)
    demo = synthetic_demo(T=12)
    times = np.cumsum([0.0] + [0.04] * 5 + [0.25] * 6)  # 25 fps, then slowed 6x (a retimed stretch)
    page = export_html(tmp_path / "viewer.html", robot, q, demo=demo, times=times).read_text(encoding="utf-8")
    clips = _clips(page)
    assert any(p.startswith("/meshcat/robot/") for p in clips) and any(p.startswith("/meshcat/human/") for p in clips)
    for path, clip in clips.items():  # robot and human alike
        for keys in _key_seconds(clip):
            np.testing.assert_allclose(keys, times, atol=1e-9, err_msg=path)
    plain = _clips(export_html(tmp_path / "plain.html", robot, q, demo=demo).read_text(encoding="utf-8"))
    keys = _key_seconds(next(iter(plain.values())))[0]
    np.testing.assert_allclose(keys, np.arange(12) / demo.fps)  # no times: the recording's rate


@pytest.mark.slow
def test_viewer_time_base_survives_decimation(robot):
    from nlo_lab.viz.export import VIEWER_MAX_FRAMES, static_html

    T = 2 * VIEWER_MAX_FRAMES + 7  # decimated to every 3rd frame
    q = np.zeros((T, robot.n_joints))
    rng = np.random.default_rng(1)
    times = np.concatenate([[0.0], np.cumsum(rng.uniform(0.01, 0.2, T - 1))])
    clips = _clips(static_html(robot, q, fps=50.0, times=times, single_precision=False))
    keys = _key_seconds(next(iter(clips.values())))[0]
    np.testing.assert_allclose(keys, times[::3], rtol=1e-12)
    assert keys[-1] == pytest.approx(times[-1 - (T - 1) % 3])


@pytest.mark.parametrize("bad", [np.arange(5.0), np.array([0.0, 1.0, 1.0] + [2.0 + i for i in range(9)])])
def test_viewer_refuses_times_that_do_not_fit(bad, tmp_path, robot):
    with pytest.raises(NloLabError, match="times"):
        export_html(tmp_path / "viewer.html", robot, sweep(robot, T=12), times=bad)
    assert not (tmp_path / "viewer.html").exists()
