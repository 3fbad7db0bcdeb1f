"""docs/ROBOT_FACTS.md against the robot files: the repository's facts page cannot drift.

Every table row of the page that names a joint is compared with the URDF (read with
yourdfpy, independent of the package's loader), the spec's ``velocity_limits`` (the
ones the package uses; the URDFs' velocity attributes are unused) and
``load_robot``'s limits; every actuated joint must appear exactly once.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

yourdfpy = pytest.importorskip("yourdfpy")
Rotation = pytest.importorskip("scipy.spatial.transform").Rotation

from nlo_lab.robot import load_robot  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
FACTS = REPO / "docs" / "ROBOT_FACTS.md"
ROBOTS = REPO / "assets" / "robots"
NAMES = ("yumi", "nao", "pepper")


def rpy_matrix(rpy) -> np.ndarray:
    """URDF roll-pitch-yaw: about the fixed x, then y, then z axes (R = Rz Ry Rx)."""
    return Rotation.from_euler("xyz", rpy).as_matrix()


def sections() -> dict[str, str]:
    """Robot name -> the text of its ``## ... (`name`)`` section."""
    out: dict[str, str] = {}
    for block in re.split(r"^## ", FACTS.read_text(encoding="utf-8"), flags=re.M)[1:]:
        found = re.match(r"[^\n]*\(`(\w+)`\)", block)
        if found:
            out[found.group(1)] = block
    return out


def tables(text: str) -> list[list[dict[str, str]]]:
    """Markdown tables of ``text`` as lists of {header: cell} rows (backticks stripped)."""
    result, header, rows = [], None, []
    for line in [*text.splitlines(), ""]:
        if line.startswith("|"):
            cells = [c.strip().strip("`") for c in line.strip().strip("|").split("|")]
            if header is None:
                header = cells
            elif not set("".join(cells)) <= set("-: "):
                rows.append(dict(zip(header, cells, strict=True)))
        elif header is not None:
            result.append(rows)
            header, rows = None, []
    return result


def numbers(cell: str) -> list[float]:
    return [float(v) for v in cell.split()]


@pytest.fixture(scope="module")
def facts() -> dict[str, str]:
    found = sections()
    assert sorted(found) == sorted(NAMES), f"robot sections in {FACTS.name}: {sorted(found)}"
    return found


@pytest.mark.parametrize("name", NAMES)
def test_joint_rows_match_the_robot_files(facts, name):
    urdf = yourdfpy.URDF.load(ROBOTS / f"{name}.urdf", build_scene_graph=False, load_meshes=False)
    spec = json.loads((ROBOTS / f"{name}.json").read_text())
    robot = load_robot(name)
    limits = dict(zip(robot.joint_names, zip(robot.lower_limits.tolist(), robot.upper_limits.tolist(), strict=True), strict=True))
    seen: list[str] = []
    for table in tables(facts[name]):
        for row in table:
            joint_name = row.get("joint")
            if joint_name not in limits:
                continue
            seen.append(joint_name)
            joint = urdf.joint_map[joint_name]
            if "parent -> child" in row:
                assert row["parent -> child"] == f"{joint.parent} -> {joint.child}", joint_name
            if "origin xyz" in row:
                np.testing.assert_allclose(joint.origin[:3, 3], numbers(row["origin xyz"]), atol=1e-6, err_msg=joint_name)
            if "origin rpy" in row:
                np.testing.assert_allclose(joint.origin[:3, :3], rpy_matrix(numbers(row["origin rpy"])), atol=1e-5, err_msg=joint_name)
            if "axis" in row:
                np.testing.assert_allclose(joint.axis, numbers(row["axis"]), atol=1e-9, err_msg=joint_name)
            lower, upper = float(row["lower"]), float(row["upper"])
            assert (joint.limit.lower, joint.limit.upper) == pytest.approx((lower, upper), abs=1e-6), joint_name
            assert limits[joint_name] == pytest.approx((lower, upper), abs=1e-6), joint_name
            velocity = float(row["max velocity"])
            assert spec["velocity_limits"][joint_name] == pytest.approx(velocity, abs=1e-6), joint_name
    assert sorted(seen) == sorted(robot.joint_names), "each actuated joint exactly once in the page"


def test_coupled_joints_match_the_urdf(facts):
    urdf = yourdfpy.URDF.load(ROBOTS / "yumi.urdf", build_scene_graph=False, load_meshes=False)
    mimics = {j.name: j.mimic for j in urdf.joint_map.values() if j.mimic is not None}
    rows = [row for table in tables(facts["yumi"]) for row in table if "coupled joint" in row]
    assert sorted(row["coupled joint"] for row in rows) == sorted(mimics)
    for row in rows:
        mimic = mimics[row["coupled joint"]]
        assert mimic.joint == row["follows"]
        assert (mimic.multiplier, mimic.offset) == pytest.approx((float(row["multiplier"]), float(row["offset"])), abs=1e-9)


def test_capsule_table_matches_the_specs():
    rows = [row for table in tables(FACTS.read_text(encoding="utf-8")) for row in table if "thinned copies" in row]
    assert sorted(row["robot"] for row in rows) == sorted(NAMES)
    for row in rows:
        spec = json.loads((ROBOTS / f"{row['robot']}.json").read_text())
        thinned = sum("~" in c["name"] for c in spec["capsules"])
        assert len(spec["capsules"]) - thinned == int(row["capsules"]) and thinned == int(row["thinned copies"])
        assert len(spec["collision_pairs"]) == int(row["pairs"])
        assert spec["collision_margin"]["default"] == pytest.approx(float(row["margin default"]))
        assert len(spec["collision_margin"]) - 1 == int(row["pairs with their own margin"])