"""``nlo-lab robot init`` and ``robot check`` on URDFs we craft: good ones drafted, hostile ones refused in one line."""

from __future__ import annotations

import contextlib
import io
import json
import struct
import sys

import pytest
import trimesh

from nlo_lab.cli import main

# A small two-armed robot: a torso, two 3-joint arms, a two-finger hand on the left.
ARM = """
  <joint name="{s}_shoulder_pitch" type="revolute"><parent link="torso"/><child link="{s}_shoulder"/>
    <origin xyz="0 {y} 0.3"/><axis xyz="0 1 0"/><limit lower="-2" upper="2" velocity="{v}" effort="1"/></joint>
  <link name="{s}_shoulder"><collision><geometry><sphere radius="0.04"/></geometry></collision></link>
  <joint name="{s}_shoulder_roll" type="revolute"><parent link="{s}_shoulder"/><child link="{s}_upper_arm"/>
    <axis xyz="1 0 0"/>{limit}</joint>
  <link name="{s}_upper_arm"><collision><origin xyz="0 0 -0.12"/><geometry><cylinder radius="0.03" length="0.24"/></geometry></collision></link>
  <joint name="{s}_elbow" type="revolute"><parent link="{s}_upper_arm"/><child link="{s}_forearm"/>
    <origin xyz="0 0 -0.25"/><axis xyz="0 1 0"/><limit lower="-2.5" upper="0" velocity="3" effort="1"/></joint>
  <link name="{s}_forearm"><collision><origin xyz="0 0 -0.11"/><geometry><cylinder radius="0.025" length="0.22"/></geometry></collision></link>
  <joint name="{s}_wrist_roll" type="continuous"><parent link="{s}_forearm"/><child link="{s}_hand"/>
    <origin xyz="0 0 -0.23"/><axis xyz="0 0 1"/></joint>
  <link name="{s}_hand"><visual><origin xyz="0 0 -0.04"/><geometry>{hand}</geometry></visual></link>
"""
FINGERS = """
  <joint name="l_thumb_joint" type="revolute"><parent link="l_hand"/><child link="l_thumb"/><origin xyz="0.02 0 -0.06"/>
    <axis xyz="0 1 0"/><limit lower="0" upper="1.5" velocity="2" effort="1"/></joint>
  <link name="l_thumb"><collision><origin xyz="0 0 -0.02"/><geometry><box size="0.01 0.01 0.04"/></geometry></collision></link>
  <joint name="l_thumb_tip_joint" type="fixed"><parent link="l_thumb"/><child link="l_thumb_tip"/><origin xyz="0 0 -0.04"/></joint>
  <link name="l_thumb_tip"/>
  <joint name="l_index_joint" type="revolute"><parent link="l_hand"/><child link="l_index"/><origin xyz="-0.02 0 -0.08"/>
    <axis xyz="0 1 0"/><limit lower="0" upper="1.5" velocity="2" effort="1"/></joint>
  <link name="l_index"><collision><origin xyz="0 0 -0.025"/><geometry><box size="0.01 0.01 0.05"/></geometry></collision></link>
  <joint name="l_index_mid" type="revolute"><parent link="l_index"/><child link="l_index_tip"/><origin xyz="0 0 -0.05"/>
    <axis xyz="0 1 0"/><mimic joint="l_index_joint" multiplier="0.8"/><limit lower="0" upper="1.2" velocity="2" effort="1"/></joint>
  <link name="l_index_tip"/>
"""
LIMIT = '<limit lower="-1" upper="1" velocity="3" effort="1"/>'


def urdf_text(*, limit: str = LIMIT, hand: str = '<box size="0.06 0.02 0.08"/>', extra: str = "", right: bool = True,
              left_velocity: str = "3", head: str = '<?xml version="1.0"?>') -> str:
    arms = ARM.format(s="l", y=0.2, v=left_velocity, limit=limit, hand=hand) + FINGERS
    if right:
        arms += ARM.format(s="r", y=-0.2, v="3", limit=LIMIT, hand='<box size="0.06 0.02 0.08"/>')
    return f"""{head}
<robot name="tiny">
  <link name="base"><collision><origin xyz="0 0 -0.05"/><geometry><box size="0.3 0.3 0.1"/></geometry></collision></link>
  <joint name="lift" type="prismatic"><parent link="base"/><child link="torso"/><axis xyz="0 0 1"/>
    <limit lower="0" upper="0.3" velocity="0.1" effort="1"/></joint>
  <link name="torso"><collision><origin xyz="0 0 0.15"/><geometry><box size="0.15 0.25 0.3"/></geometry></collision></link>
  <joint name="head_yaw" type="revolute"><parent link="torso"/><child link="head"/><origin xyz="0 0 0.45"/>
    <axis xyz="0 0 1"/><limit lower="0.2" upper="1" velocity="1" effort="1"/></joint>
  <link name="head"><visual><geometry><sphere radius="0.08"/></geometry></visual></link>
{arms}{extra}
</robot>
"""


def run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def tiny(tmp_path):
    path = tmp_path / "tiny.urdf"
    path.write_text(urdf_text(left_velocity="0"))
    return path


@pytest.fixture(scope="module")
def drafted(tmp_path_factory):
    """``nlo-lab robot init tiny.urdf --out out/tiny.json`` run once for the tests that read its default draft
    (drafting the capsules is the costly part): the spec's path, the exit status, stdout and stderr."""
    folder = tmp_path_factory.mktemp("drafted")
    (folder / "tiny.urdf").write_text(urdf_text(left_velocity="0"))
    spec = folder / "out" / "tiny.json"
    spec.parent.mkdir()
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["robot", "init", str(folder / "tiny.urdf"), "--out", str(spec)])
    return spec, code, out.getvalue(), err.getvalue()


def test_init_drafts_a_complete_spec_and_check_reads_it_back(drafted, capsys):
    spec, code, out, err = drafted
    assert code == 0, err
    # the six links it chose are printed, and the summary
    for name in ("l_shoulder", "l_forearm", "l_hand", "r_shoulder", "r_forearm", "r_hand"):
        assert name in out
    assert "wrote" in out and "actuated joints" in out and "capsules" in out
    # the velocity limit the URDF does not give: a warning naming the joint, the stated default
    assert "l_shoulder_pitch" in err and "2.0 rad/s" in err
    assert "capsule pairs" not in err  # no progress bar where stderr is not a terminal
    data = json.loads(spec.read_text())
    assert data["urdf"] == "../tiny.urdf"
    # actuated: the arm chains (the joint whose child is the shoulder too), the finger chains with the
    # mimic joint's source; fixed: the lift (prismatic) at 0, the head at its limit nearest 0
    assert data["actuated_joints"][:4] == ["l_shoulder_pitch", "l_shoulder_roll", "l_elbow", "l_wrist_roll"]
    assert {"l_thumb_joint", "l_index_joint"} <= set(data["actuated_joints"]) and "l_index_mid" not in data["actuated_joints"]
    assert data["fixed_joints"] == {"lift": 0.0, "head_yaw": 0.2}
    assert data["velocity_limits"]["l_shoulder_pitch"] == 2.0 and data["velocity_limits"]["l_elbow"] == 3.0
    assert data["arms"]["left"]["fingers"] == {"thumb": ["l_thumb", "l_thumb_tip"], "index": ["l_index", "l_index_tip"]}
    assert "fingers" not in data["arms"]["right"]
    assert "continuous joints are limited to [-pi, pi] rad: l_wrist_roll, r_wrist_roll" in out
    code, out, err = run(["robot", "check", spec], capsys)
    assert code == 0, err
    assert "left  arm: 4 joints" in out and "fingers thumb, index (each with a joint of its own)" in out
    assert "at the rest pose no checked pair" in out


def test_init_refuses_to_replace_a_spec_unless_forced(tiny, tmp_path, capsys, monkeypatch, assert_one_line_error):
    spec = tmp_path / "tiny.json"
    spec.write_text("{}")
    code, _, err = run(["robot", "init", tiny, "--out", spec], capsys)
    assert_one_line_error(code, err, "exists", "--force")
    assert spec.read_text() == "{}"
    terminal = Terminal()  # and on a terminal, the draft shows its progress on stderr
    monkeypatch.setattr(sys, "stderr", terminal)
    code, _, err = run(["robot", "init", tiny, "--out", spec, "--force"], capsys)
    assert code == 0 and json.loads(spec.read_text())["name"] == "tiny"
    assert "weighing capsule pairs" in terminal.getvalue() and "checking capsule pairs" in terminal.getvalue()


class Terminal(io.StringIO):
    """A stderr that says it is a terminal."""

    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize("quiet", [False, True])
def test_init_shows_progress_on_a_terminal_unless_quiet(tiny, tmp_path, capsys, monkeypatch, quiet):
    """The draft gets ``progress=True`` on a terminal without ``--quiet`` (the bar itself: the test above)."""
    import nlo_lab.robot.spec_draft as spec_draft
    from nlo_lab.errors import RobotDescriptionError

    asked = []

    def draft_spec(*args, progress=False, **kwargs):
        asked.append(progress)
        raise RobotDescriptionError("stopped here")

    monkeypatch.setattr(spec_draft, "draft_spec", draft_spec)
    monkeypatch.setattr(sys, "stderr", Terminal())
    code, _, _ = run(["robot", "init", tiny, "--out", tmp_path / "x.json", *(["--quiet"] if quiet else [])], capsys)
    assert code == 2 and asked == [not quiet]


def test_given_arms_and_hands_and_unknown_links(tiny, tmp_path, capsys, assert_one_line_error):
    spec = tmp_path / "tiny.json"
    code, out, err = run(["robot", "init", tiny, "--out", spec, "--left-arm", "l_upper_arm,l_forearm,l_hand",
                          "--right-arm", "r_upper_arm,r_forearm,r_hand", "--left-hand", "none"], capsys)
    assert code == 0, err
    data = json.loads(spec.read_text())
    assert data["arms"]["left"]["shoulder"] == "l_upper_arm" and "fingers" not in data["arms"]["left"]
    assert "arms found" not in out
    code, _, err = run(["robot", "init", tiny, "--out", tmp_path / "x.json", "--left-arm", "l_upper_arm,l_forarm,l_hand",
                        "--right-arm", "r_upper_arm,r_forearm,r_hand"], capsys)
    assert_one_line_error(code, err, "'l_forarm'", "closest: l_forearm")
    code, _, err = run(["robot", "init", tiny, "--out", tmp_path / "x.json", "--left-hand", "thumb=l_thumb_tip,palm=l_hand"], capsys)
    assert_one_line_error(code, err, "unknown finger 'palm'")
    code, _, err = run(["robot", "init", tiny, "--out", tmp_path / "x.json", "--left-arm", "l_upper_arm,l_forearm"], capsys)
    assert_one_line_error(code, err, "SHOULDER,ELBOW,WRIST")


def test_check_names_an_unknown_link_with_the_closest_names(drafted, capsys, assert_one_line_error):
    drafted_spec, code, _, err = drafted
    assert code == 0, err
    data = json.loads(drafted_spec.read_text())
    data["arms"]["right"]["elbow"] = "r_fore_arm"
    spec = drafted_spec.with_name("misnamed.json")  # beside it: the same path to the URDF
    spec.write_text(json.dumps(data))
    code, _, err = run(["robot", "check", spec], capsys)
    assert_one_line_error(code, err, "arms.right.elbow", "'r_fore_arm'", "closest: r_forearm")


HOSTILE = {
    "entities": dict(head='<?xml version="1.0"?><!DOCTYPE robot [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;">]>'),
    "external entity": dict(head='<?xml version="1.0"?><!DOCTYPE robot [<!ENTITY x SYSTEM "file:///etc/passwd">]>'),
    "escaping package path": dict(hand='<mesh filename="package://tiny/../../secret.stl"/>'),
    "escaping relative path": dict(hand='<mesh filename="../secret.stl"/>'),
    "absolute path elsewhere": dict(hand='<mesh filename="/etc/hosts.stl"/>'),
    "one arm": dict(right=False),
    "no limit on an actuated joint": dict(limit=""),
    "a cycle": dict(extra='<joint name="loop" type="fixed"><parent link="l_hand"/><child link="torso"/></joint>'),
}
REASON = {
    "entities": "DTD", "external entity": "DTD", "escaping package path": "outside the URDF's folder tree",
    "escaping relative path": "outside the URDF's folder tree", "absolute path elsewhere": "outside the URDF's folder tree",
    "one arm": "no two arms", "no limit on an actuated joint": "l_shoulder_roll' on the left arm has no <limit>",
    "a cycle": "two parent joints",
}


@pytest.mark.parametrize("case", sorted(HOSTILE))
def test_hostile_urdfs_are_refused_in_one_line(case, tmp_path, capsys, assert_one_line_error):
    folder = tmp_path / "tiny"
    folder.mkdir()
    (tmp_path / "secret.stl").write_bytes(b"solid secret\nendsolid secret\n")
    urdf = folder / "tiny.urdf"
    urdf.write_text(urdf_text(**HOSTILE[case]))
    code, _, err = run(["robot", "init", urdf, "--out", tmp_path / "x.json"], capsys)
    assert_one_line_error(code, err, REASON[case])
    assert not (tmp_path / "x.json").exists()


def test_a_xacro_file_gets_the_line_that_expands_it(tmp_path, capsys, assert_one_line_error):
    urdf = tmp_path / "robot.urdf.xacro"
    urdf.write_text('<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro"><xacro:property name="l" value="1"/></robot>')
    code, _, err = run(["robot", "init", urdf, "--out", tmp_path / "x.json"], capsys)
    assert_one_line_error(code, err, "xacro file", "xacro", "> robot.urdf")
    plain = tmp_path / "expanded.urdf"
    plain.write_text('<robot name="r"><link name="a" xmlns:x="x"><visual><geometry><box size="${l} 1 1"/></geometry></visual></link></robot>')
    code, _, err = run(["robot", "init", plain, "--out", tmp_path / "x.json"], capsys)
    assert_one_line_error(code, err, "xacro file")


def test_huge_and_missing_meshes(tmp_path, capsys, assert_one_line_error):
    """A mesh declaring 50 million triangles is refused before it is read; a missing one is a warning and a stand-in."""
    (tmp_path / "meshes").mkdir()
    huge = tmp_path / "meshes" / "huge.stl"
    huge.write_bytes(b"\0" * 80 + struct.pack("<I", 50_000_000) + b"\0" * 50)
    urdf = tmp_path / "tiny.urdf"
    urdf.write_text(urdf_text(hand='<mesh filename="meshes/huge.stl"/>'))
    code, _, err = run(["robot", "init", urdf, "--out", tmp_path / "x.json"], capsys)
    assert_one_line_error(code, err, "huge.stl", "50000000 triangles")
    trimesh.creation.box(extents=(0.06, 0.02, 0.08)).export(tmp_path / "meshes" / "hand.stl")
    urdf.write_text(urdf_text(hand='<mesh filename="meshes/hand.stl"/>').replace('<box size="0.06 0.02 0.08"/>', '<mesh filename="meshes/gone.stl"/>'))
    code, out, err = run(["robot", "init", urdf, "--out", tmp_path / "x.json"], capsys)
    assert code == 0, err
    assert "gone.stl is missing" in err


def test_the_base_flag(tiny, tmp_path, capsys, assert_one_line_error):
    """--base: the link the arms hang from; the joints above it stay fixed, those below it on the way to the
    shoulders are actuated, so it must sit above both shoulders and below every joint nlo_lab cannot actuate."""
    spec = tmp_path / "tiny.json"
    code, _, err = run(["robot", "init", tiny, "--out", spec, "--base", "torso"], capsys)
    assert code == 0, err
    data = json.loads(spec.read_text())
    assert data["base_link"] == "torso" and data["fixed_joints"]["lift"] == 0.0
    code, _, err = run(["robot", "init", tiny, "--out", tmp_path / "x.json", "--base", "l_hand"], capsys)
    assert_one_line_error(code, err, "--base 'l_hand' is not above the left shoulder")
    code, _, err = run(["robot", "init", tiny, "--out", tmp_path / "x.json", "--base", "base"], capsys)
    assert_one_line_error(code, err, "prismatic joint 'lift'", "--base")
    code, _, err = run(["robot", "init", tiny, "--out", tmp_path / "x.json", "--base", "torsoo"], capsys)
    assert_one_line_error(code, err, "'torsoo'", "closest: torso")
    assert not (tmp_path / "x.json").exists()
