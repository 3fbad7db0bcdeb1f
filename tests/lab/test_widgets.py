"""The ipywidgets panels, driven headlessly: set a control, the pose and the plot change."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import umsgpack

from nlo_lab.errors import SettingsError
from nlo_lab.human import load_demonstration
from nlo_lab.lab import JointPanel, RetargetPanel, budget, is_test_mode, recording_path, show_robot, show_view, svg_convergence
from nlo_lab.robot import load_robot
from nlo_lab.training import new_model
from nlo_lab.viz import SceneWidget, recording_visualizer


@pytest.fixture(scope="module")
def demo():
    return load_demonstration(recording_path()).slice(10, 16)  # 6 frames of the shipped real recording


def _loader(robot):
    torch.manual_seed(0)  # an untrained model: the panels' plumbing does not depend on training
    return new_model(robot, in_features=13)


@pytest.fixture
def panel(demo):
    return RetargetPanel(demo, "nao", model_loader=_loader, iterations=6, frame_iterations=4, view=None)


def _changed(panel, action):
    q, plot, data = panel.q.copy(), panel.plot.value, panel.plot_data
    action()
    return float(np.abs(panel.q - q).max()), panel.plot.value != plot, panel.plot_data != data


def test_weight_slider_reoptimises_the_current_frame(panel):
    dq, plot_changed, data_changed = _changed(panel, lambda: setattr(panel.controls["ee"], "value", 10.0))
    assert panel.weights.ee == pytest.approx(10.0)
    assert dq > 1e-6 and plot_changed and data_changed
    assert 1 <= len(panel.history) <= 4 + 1  # warm start: at most frame_iterations steps
    assert panel.history == panel.plot_data[-1][1]


def test_init_and_iterations_restart_from_the_chosen_initialisation(panel):
    dq, plot_changed, _ = _changed(panel, lambda: setattr(panel.controls["init"], "value", "random"))
    assert dq > 1e-6 and plot_changed
    assert panel.last.init == "random" and len(panel.history) == 6 + 1  # full budget, untrained: no early stop
    dq, plot_changed, _ = _changed(panel, lambda: setattr(panel.controls["iterations"], "value", 10))
    assert plot_changed and len(panel.history) == 10 + 1


def test_frame_scrubber_and_play_are_linked(panel, demo):
    before = panel.angles.copy()
    panel.play.value = 3  # the Play widget drives the frame slider
    assert panel.controls["frame"].value == 3 and panel.frame == 3
    changed = np.abs(panel.angles - before).max(axis=1) > 1e-9
    assert changed[3] and not changed[[0, 1, 2, 4, 5]].any()  # only the current frame was re-optimised
    assert panel.plot_data[-1][0].startswith("frame 3")


def test_robot_switch_changes_the_joint_space(panel):
    assert panel.q.shape == (10,)
    panel.controls["robot"].value = "pepper"
    assert panel.robot.name == "pepper" and panel.q.shape == (panel.robot.n_joints,)
    lo, hi = panel.robot.lower_limits.numpy(), panel.robot.upper_limits.numpy()
    assert np.all(panel.angles >= lo - 1e-5) and np.all(panel.angles <= hi + 1e-5)  # the decoder keeps the limits


def test_sequence_button_optimises_every_frame(panel, demo):
    before = panel.angles.copy()
    panel.button.click()
    assert panel.last.q.shape[0] == len(demo)
    assert (np.abs(panel.angles - before).max(axis=1) > 1e-9).sum() >= len(demo) - 1
    assert panel.plot_data[-1][0].startswith("sequence")


def test_view_is_updated_when_injected(demo):
    vis = recording_visualizer()
    p = RetargetPanel(demo, "nao", model_loader=_loader, iterations=4, frame_iterations=3, view=vis)
    page = vis.static_html()
    p.controls["collision"].value = 1.0
    assert vis.static_html() != page  # the robot moved in the scene


def test_widget_view_sends_only_transforms_per_move(demo):
    p = RetargetPanel(demo, "nao", model_loader=_loader, iterations=3, frame_iterations=2)
    widget = p._view.widget
    sent = []
    widget.send = lambda content, buffers=None: sent.append((content, [bytes(b) for b in (buffers or [])]))
    p.controls["collision"].value = 3.0  # same frame: the robot moves, the human does not
    p.controls["frame"].value = 2  # a new frame: robot and human move
    assert len(sent) == 2, "one message per move"
    for _content, (data,) in sent:
        cmds, at = [], 0
        while at < len(data):
            n = int.from_bytes(data[at:at + 4], "little")
            cmds.append(umsgpack.unpackb(data[at + 4:at + 4 + n]))
            at += 4 + n
        assert {c["type"] for c in cmds} == {"set_transform"}, "a move re-sends no geometry"
        assert len(data) < 20_000
    paths = [[c for c in _paths(data)] for _, (data,) in sent]
    assert not any("/human/" in x for x in paths[0]) and any("/human/" in x for x in paths[1])


def _paths(data: bytes) -> list[str]:
    out, at = [], 0
    while at < len(data):
        n = int.from_bytes(data[at:at + 4], "little")
        out.append(umsgpack.unpackb(data[at + 4:at + 4 + n])["path"])
        at += 4 + n
    return out


def test_play_shows_frames_without_reoptimising(demo):
    p = RetargetPanel(demo, "nao", model_loader=_loader, iterations=3, frame_iterations=2, view=None)
    before, last = p.angles.copy(), p.last
    p.play.playing = True
    times = p.play_times()
    assert p.play.interval == round(1000 * times[-1] / (len(times) - 1)), "Play ticks at the clip's own (retimed) rate"
    p.play.value = 3
    assert p.frame == 3 and p.last is last and np.array_equal(p.angles, before)
    p.play.playing = False
    p.controls["frame"].value = 4
    assert p.last is not last  # scrubbing by hand re-optimises


def test_play_runs_in_the_page_as_an_animation(demo):
    p = RetargetPanel(demo, "nao", model_loader=_loader, iterations=3, frame_iterations=2)
    widget = p._view.widget
    sent = []
    widget.send = lambda content, buffers=None: sent.append([c["type"] for c in _unpack_all(buffers[0])])
    p.play.playing = True
    assert sent == [["set_animation"]], "Play starts: the whole clip goes to the page once"
    for t in range(1, 4):
        p.play.value = t  # the Play widget ticks: the page animates, the kernel sends nothing
    assert len(sent) == 1 and p.frame == 3
    p.play.playing = False
    assert sent[-1][0] == "set_animation" and sent[-1].count("set_transform") >= len(p.scene.robot_scene.links)
    # One time base: Play's slider ticks T - 1 times, interval ms apart, while the page's animation runs from
    # its first key to its last. With a jump the retiming slows down (not the recording's 1/fps), both
    # still last the clip's duration on the trajectory's time base.
    p.angles[len(p.angles) // 2:] += 0.5
    p.scene.angles[:] = p.angles
    p.play.playing = True
    sent.clear()
    widget.send = lambda content, buffers=None: sent.append(_unpack_all(buffers[0]))
    p.play.playing = False
    p.play.playing = True
    (anim,) = [c for c in sent[-1] if c["type"] == "set_animation"]
    duration = max(key["time"] / a["clip"]["fps"] for a in anim["animations"] for track in a["clip"]["tracks"] for key in track["keys"])
    T = len(p.angles)
    assert duration == pytest.approx(p.play_times()[-1]) and duration > (T - 1) / demo.fps + 0.02, "the jump is slowed"
    assert abs(p.play.interval * (T - 1) / 1000 - duration) <= 0.0005 * (T - 1), (p.play.interval, duration)


def _unpack_all(data) -> list[dict]:
    data, out, at = bytes(data), [], 0
    while at < len(data):
        n = int.from_bytes(data[at:at + 4], "little")
        out.append(umsgpack.unpackb(data[at + 4:at + 4 + n]))
        at += 4 + n
    return out


def test_callback_errors_are_shown_in_the_panel(demo, monkeypatch):
    p = RetargetPanel(demo, "nao", model_loader=_loader, iterations=3, frame_iterations=2)

    def broken(*args, **kwargs):
        raise RuntimeError("the optimiser broke")

    monkeypatch.setattr("nlo_lab.pipeline.Retargeter.optimize", broken)
    with pytest.raises(RuntimeError, match="broke"):
        p.controls["ee"].value = 10.0
    assert "the optimiser broke" in p.error and "nlo-lab-panel-error" in p.status.value
    assert "the optimiser broke" in p._view.widget.message
    monkeypatch.undo()
    p.controls["ee"].value = 20.0
    assert p.error == "" and p._view.widget.message == "" and "error" not in p.status.value


def test_bad_arguments(demo):
    with pytest.raises(SettingsError, match="init"):
        RetargetPanel(demo, "nao", model_loader=_loader, init="magic", view=None)
    with pytest.raises(SettingsError, match="frame 99"):
        RetargetPanel(demo, "nao", model_loader=_loader, frame=99, view=None)
    with pytest.raises(SettingsError, match="view"):
        RetargetPanel(demo, "nao", model_loader=_loader, view="3d")
    with pytest.raises(SettingsError, match="view"):
        RetargetPanel(demo, "nao", model_loader=_loader, view="static")  # the per-update static page is gone


def test_joint_panel_moves_the_link():
    robot = load_robot("nao")
    vis = recording_visualizer()
    jp = JointPanel(robot, view=vis)
    arm = robot.arm("left")
    jp.link.value = arm.wrist
    pos, page = jp.position.copy(), vis.static_html()
    name = robot.joint_names[0]
    s = jp.sliders[name]
    s.value = s.min if s.value - s.min > s.max - s.value else s.max
    assert np.linalg.norm(jp.position - pos) > 1e-3 and vis.static_html() != page
    q = torch.as_tensor(jp.q, dtype=robot.lower_limits.dtype)[None]
    expected = robot.forward_kinematics(q)[arm.wrist][0, :3, 3].numpy()
    np.testing.assert_allclose(jp.position, expected, atol=1e-6)


def test_svg_convergence():
    svg = svg_convergence([("a", [10.0, 5.0, 1.0]), ("b", [3.0])])
    assert svg.startswith("<svg") and svg.count("<polyline") == 2 and "(log)" in svg
    assert "(log)" not in svg_convergence([("a", [1.0, -1.0])])
    assert svg_convergence([]).startswith("<svg")


def test_notebook_helpers(monkeypatch):
    monkeypatch.setenv("NLO_LAB_TEST_MODE", "1")
    assert is_test_mode() and budget(100, 3) == 3
    monkeypatch.setenv("NLO_LAB_TEST_MODE", "0")
    assert budget(100, 3) == 100
    robot = load_robot("nao")
    a, b = show_robot(robot), show_robot(load_robot("yumi"))
    assert isinstance(a, SceneWidget) and a.message == "" and a.vis.window.tree is not b.vis.window.tree
    paths_a, paths_b = ({c["path"] for c in _commands(w)} for w in (a, b))
    assert "/meshcat/robot/Head" in paths_a and not any("yumi_" in x for x in paths_a)  # NAO stays NAO ...
    assert "/meshcat/robot/yumi_link_7_l" in paths_b and "/meshcat/robot/Head" not in paths_b  # ... YuMi's scene is its own
    assert show_view(robot, np.zeros((5, robot.n_joints))).scene is not None


def _commands(widget) -> list[dict]:
    data, out, at = widget.snapshot(), [], 0
    while at < len(data):
        n = int.from_bytes(data[at:at + 4], "little")
        out.append(umsgpack.unpackb(data[at + 4:at + 4 + n]))
        at += 4 + n
    return out


def test_views_show_bad_input_in_the_widget():
    robot = load_robot("nao")
    cases = {
        "unknown robot 'nao2'": show_robot("nao2"),
        "not finite": show_robot(robot, np.full(robot.n_joints, np.nan)),
        "one pose": show_robot(robot, np.zeros((2, robot.n_joints))),
        "must be": show_view(robot, np.zeros((3, 4))),
    }
    for expected, widget in cases.items():
        assert isinstance(widget, SceneWidget) and expected in widget.message, widget.message
        assert widget.message.startswith("Cannot show this view")


def test_play_animates_on_the_robots_time_base(demo):
    """Play shows what the robot would play: the keys sit at the retimed times, not at the recording's rate."""
    p = RetargetPanel(demo, "nao", model_loader=_loader, iterations=3, frame_iterations=2)
    lo, hi = p.robot.lower_limits.double().numpy(), p.robot.upper_limits.double().numpy()
    p.angles = np.where(np.arange(len(demo))[:, None] % 2 == 0, lo, hi) * 0.9  # too fast for any joint: retimed
    times = p.play_times()
    assert times[-1] > 2 * (len(demo) - 1) / demo.fps
    sent = []
    p._view.widget.send = lambda content, buffers=None: sent.append(_unpack_all(buffers[0]))
    p.play.playing = True
    (anim,) = [c for c in sent[0] if c["type"] == "set_animation"]
    for a in anim["animations"]:
        for track in a["clip"]["tracks"]:
            np.testing.assert_allclose(np.array([k["time"] for k in track["keys"]]) / a["clip"]["fps"], times, rtol=1e-6)
    p.play.playing = False
