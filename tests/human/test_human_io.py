"""Reading and writing demonstrations: our .npz, the authors' HDF5 layout, dispatch, bad input."""

from __future__ import annotations

import json
import os

import h5py
import numpy as np
import pytest

from nlo_lab.errors import DemonstrationError
from nlo_lab.human import Demonstration, load_demonstration, load_h5_sequences, save_npz
from nlo_lab.human.transforms import quat_to_matrix


def _files(folder):
    return sorted(p.name for p in folder.iterdir())


# ---------------------------------------------------------------- npz
def test_npz_round_trip_is_exact(tmp_path, make_demo):
    demo = make_demo()
    demo.arm_mask[3, 0, 1] = False
    demo.wrist_mask[5, 1] = False
    demo.finger_mask[7, 0, 2] = False
    demo.meta = {"scenario": "hospital", "signer": 3, "nested": {"a": [1, 2.5]}}
    demo.validate()
    path = save_npz(demo, tmp_path / "d.npz")
    back = load_demonstration(path)
    assert back.fps == demo.fps and back.name == demo.name and back.meta == demo.meta
    for field in ("arm_positions", "arm_mask", "wrist_rotations", "wrist_mask", "finger_positions", "finger_mask"):
        a, b = getattr(demo, field), getattr(back, field)
        assert a.dtype == b.dtype
        np.testing.assert_array_equal(a, b)  # NaN == NaN for array_equal on float arrays
    assert np.isnan(back.arm_positions[3, 0, 1]).all() and not back.arm_mask[3, 0, 1]
    assert _files(tmp_path) == ["d.npz"]  # no temporary left behind


def test_npz_stores_a_format_version(tmp_path, make_demo):
    path = save_npz(make_demo(), tmp_path / "d.npz")
    with np.load(path) as data:
        assert int(data["format_version"]) == 1
        assert json.loads(str(data["meta_json"])) == {"k": 1}


def test_npz_unsupported_version(tmp_path, make_demo):
    path = save_npz(make_demo(), tmp_path / "d.npz")
    with np.load(path) as data:
        content = dict(data)
    content["format_version"] = np.array(99)
    np.savez(tmp_path / "v.npz", **content)
    with pytest.raises(DemonstrationError, match="version"):
        load_demonstration(tmp_path / "v.npz")


def test_save_npz_failed_write_leaves_nothing(tmp_path, make_demo):
    demo = make_demo()
    demo.meta = {"not json": object()}
    with pytest.raises(DemonstrationError, match="meta"):
        save_npz(demo, tmp_path / "d.npz")
    assert _files(tmp_path) == []
    with pytest.raises(DemonstrationError):
        save_npz(make_demo(), tmp_path / "missing_dir" / "d.npz")
    assert _files(tmp_path) == []


def test_save_npz_overwrites_atomically(tmp_path, make_demo):
    path = tmp_path / "d.npz"
    save_npz(make_demo(seed=0), path)
    save_npz(make_demo(seed=1), path)
    np.testing.assert_array_equal(load_demonstration(path).finger_positions, make_demo(seed=1).finger_positions)
    assert _files(tmp_path) == ["d.npz"]


@pytest.fixture(scope="session")
def write_npz_with(make_demo):
    def build(tmp_path, **changes):
        demo = make_demo()
        path = save_npz(demo, tmp_path / "base.npz")
        with np.load(path) as data:
            content = dict(data)
        content.update(changes)
        bad = tmp_path / "bad.npz"
        np.savez(bad, **content)
        return bad

    return build


def test_npz_nan_names_frame_and_field(tmp_path, make_demo, write_npz_with):
    arms = make_demo().arm_positions.copy()
    arms[7, 1, 2, 0] = np.inf
    with pytest.raises(DemonstrationError) as err:
        load_demonstration(write_npz_with(tmp_path, arm_positions=arms))
    assert err.value.frame == 7 and err.value.field == "arm_positions" and "bad.npz" in str(err.value)


def test_npz_wrong_shape(tmp_path, write_npz_with):
    with pytest.raises(DemonstrationError, match="finger_positions") as err:
        load_demonstration(write_npz_with(tmp_path, finger_positions=np.zeros((20, 2, 5, 3))))
    assert "bad.npz" in str(err.value)


def test_npz_no_frames(tmp_path, write_npz_with):
    empty = {
        "arm_positions": np.zeros((0, 2, 3, 3)), "arm_mask": np.zeros((0, 2, 3), bool),
        "wrist_rotations": np.zeros((0, 2, 3, 3)), "wrist_mask": np.zeros((0, 2), bool),
        "finger_positions": np.zeros((0, 2, 5, 2, 3)), "finger_mask": np.zeros((0, 2, 5), bool),
    }
    with pytest.raises(DemonstrationError, match="no frames"):
        load_demonstration(write_npz_with(tmp_path, **empty))


@pytest.mark.parametrize("fps", [0.0, -1.0])
def test_npz_bad_fps(tmp_path, fps, write_npz_with):
    with pytest.raises(DemonstrationError, match="fps") as err:
        load_demonstration(write_npz_with(tmp_path, fps=np.array(fps)))
    assert err.value.field == "fps"


def test_npz_zero_length_arm(tmp_path, make_demo, write_npz_with):
    arms = make_demo().arm_positions.copy()
    arms[4, 0, 1] = arms[4, 0, 0]  # left elbow on the shoulder
    with pytest.raises(DemonstrationError, match="zero length") as err:
        load_demonstration(write_npz_with(tmp_path, arm_positions=arms))
    assert err.value.frame == 4 and err.value.field == "left/upper_arm"


def test_npz_truncated_and_garbage(tmp_path, make_demo):
    path = save_npz(make_demo(), tmp_path / "d.npz")
    data = path.read_bytes()
    (tmp_path / "cut.npz").write_bytes(data[: len(data) // 2])
    with pytest.raises(DemonstrationError, match="cut.npz"):
        load_demonstration(tmp_path / "cut.npz")
    (tmp_path / "junk.npz").write_bytes(b"hello")
    with pytest.raises(DemonstrationError, match="junk.npz"):
        load_demonstration(tmp_path / "junk.npz")
    with pytest.raises(DemonstrationError, match="no such file"):
        load_demonstration(tmp_path / "absent.npz")


def test_unknown_extension(tmp_path):
    path = tmp_path / "demo.csv"
    path.write_text("1,2,3\n")
    with pytest.raises(DemonstrationError, match="extension") as err:
        load_demonstration(path)
    assert "demo.csv" in str(err.value)


# ---------------------------------------------------------------- authors' HDF5
def test_h5_round_trip_all_groups_sorted(tmp_path, write_authors_h5):
    path = tmp_path / "signs.h5"
    truth = write_authors_h5(path, fps=20.0)
    demos = load_h5_sequences(path)
    assert [d.name for d in demos] == ["sentence_1", "word_a", "word_b"]
    assert [d.meta["is_sentence"] for d in demos] == [True, False, False]
    assert all(d.meta["group"] == d.name and d.fps == 20.0 for d in demos)
    for d in demos:
        for side, s in (("left", "l"), ("right", "r")):
            sh, el, wr = truth[d.name][s]
            np.testing.assert_allclose(d.position(side, "shoulder"), sh, atol=1e-9)
            np.testing.assert_allclose(d.position(side, "elbow"), el, atol=1e-9)
            np.testing.assert_allclose(d.position(side, "wrist"), wr, atol=1e-9)
            hand, Ry = truth[d.name][s + "_glove"]
            np.testing.assert_allclose(d.fingers(side)[:, 1, 0], wr + hand[:, 4] - hand[:, 0], atol=1e-9)  # index base
            np.testing.assert_allclose(d.fingers(side)[:, 4, 1], wr + hand[:, 15] - hand[:, 0], atol=1e-9)  # pinky tip
            R = d.wrist_rotation(side)
            assert np.all(d.wrist_mask) and np.all(d.finger_mask)
            np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-9)
            # the hand frame was turned by 0.2 rad about Y: x axis ~ Ry x (noise on the points is 1 mm)
            assert np.all(R[:, :, 0] @ Ry[:, 0] > 0.99)
    first = load_demonstration(path)
    assert first.name == "sentence_1"


def test_h5_quaternion_orientation_without_glove(tmp_path, write_authors_h5):
    path = tmp_path / "q.hdf5"
    write_authors_h5(path, groups=("g0", "g1"), glove=False, yaw=0.5)
    demos = load_h5_sequences(path)
    assert demos[0].fps == 15.0  # default
    assert not demos[0].finger_mask.any() and np.isnan(demos[0].finger_positions).all()
    # g1 has hd_quat = 0.2 rad about Z in the capture frame, which is the body frame turned by 0.5 rad about Z:
    # R_body_wrist = R_body_capture R_capture_wrist = Rz(-0.5) Rz(0.2)
    np.testing.assert_allclose(demos[1].wrist_rotation("left"), np.broadcast_to(quat_to_matrix(np.array([0, 0, np.sin(-0.15), np.cos(-0.15)])), (12, 3, 3)), atol=1e-9)
    assert demos[0].meta["wrist_orientation_from"] == {"left": "hd_quat", "right": "hd_quat"}


def test_h5_left_is_plus_y_and_origin_between_shoulders(tmp_path, write_authors_h5):
    path = tmp_path / "s.h5"
    write_authors_h5(path, yaw=2.5)  # the capture frame faces almost backwards
    d = load_demonstration(path)
    np.testing.assert_allclose(d.position("left", "shoulder") + d.position("right", "shoulder"), 0.0, atol=1e-9)
    assert np.all(d.position("left", "shoulder")[:, 1] > 0.1)
    assert np.all(d.position("left", "wrist")[:, 0] > 0.1)  # the wrists were placed 0.2 m forward


def _copy_h5_with(src, dst, group, key, value):
    with h5py.File(src, "r") as a, h5py.File(dst, "w") as b:
        for name in a:
            a.copy(name, b)
        del b[group][key]
        if value is not None:
            b[group][key] = value


@pytest.mark.parametrize(
    "key,value,match,frame",
    [
        ("l_hd_pos", "nan", "NaN", 6),
        ("r_fr_pos", np.zeros((12, 4)), "shape", None),
        ("l_up_pos", None, "missing", None),
        ("r_hd_pos", np.zeros((11, 3)), "frames", None),
        ("l_hd_pos", "zero_forearm", "zero length", 2),
    ],
)
def test_h5_bad_content_names_group_field_frame(tmp_path, key, value, match, frame, write_authors_h5):
    good = tmp_path / "good.h5"
    write_authors_h5(good, groups=("seq",))
    with h5py.File(good, "r") as f:
        arr = f["seq"][key][()]
        elbow = f["seq"]["l_fr_pos"][()]
    if isinstance(value, str) and value == "nan":
        arr[6, 1] = np.nan
        value = arr
    elif isinstance(value, str) and value == "zero_forearm":
        arr[2] = elbow[2]
        value = arr
    bad = tmp_path / "bad.h5"
    _copy_h5_with(good, bad, "seq", key, value)
    with pytest.raises(DemonstrationError, match=match) as err:
        load_h5_sequences(bad)
    assert "bad.h5" in str(err.value)
    assert err.value.frame == frame
    if match != "zero length":
        assert key in err.value.field


def test_h5_bad_fps_empty_and_truncated(tmp_path, write_authors_h5):
    path = tmp_path / "f.h5"
    write_authors_h5(path, groups=("seq",), fps=0.0)
    with pytest.raises(DemonstrationError, match="fps"):
        load_demonstration(path)
    empty = tmp_path / "e.h5"
    h5py.File(empty, "w").close()
    with pytest.raises(DemonstrationError, match="no sequence"):
        load_h5_sequences(empty)
    good = tmp_path / "g.h5"
    write_authors_h5(good, groups=("seq",), T=400)
    data = good.read_bytes()
    cut = tmp_path / "cut.h5"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(DemonstrationError, match="cut.h5"):
        load_h5_sequences(cut)
    before = _files(tmp_path)
    with pytest.raises(DemonstrationError):
        load_demonstration(tmp_path / "nothing.h5")
    assert _files(tmp_path) == before  # a failed read writes nothing


def test_readers_do_not_write(tmp_path, make_demo, write_authors_h5):
    path = tmp_path / "s.h5"
    write_authors_h5(path)
    npz = save_npz(make_demo(), tmp_path / "d.npz")
    stamp = {p.name: (p.stat().st_size, p.stat().st_mtime_ns) for p in tmp_path.iterdir()}
    load_h5_sequences(path)
    load_demonstration(npz)
    assert {p.name: (p.stat().st_size, p.stat().st_mtime_ns) for p in tmp_path.iterdir()} == stamp
    assert os.listdir(tmp_path) and isinstance(load_demonstration(npz), Demonstration)
