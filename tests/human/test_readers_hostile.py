"""The human readers against crafted files (issue 25): read only what was named, bounded memory, no silent truncation.

Every crafted file is made here from the bundled sample recording or a few arrays; each case
asserts the reader's own error and a message naming the file and what is wrong, and the
valid variants of each format are read to the same demonstration (so the checks refuse
only what they should).
"""

from __future__ import annotations

import struct
import zipfile
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from make_corpus import authors_arms  # tests/fuzz/make_corpus.py: the authors' layout of a small recording

from nlo_lab.errors import DemonstrationError
from nlo_lab.files import format_size
from nlo_lab.human import load_demonstration, save_npz
from nlo_lab.human.readers import h5 as h5_reader
from nlo_lab.human.readers import h5_extract
from nlo_lab.human.readers.pose import MAX_POSE_BYTES
from nlo_lab.paths import RECORDINGS_DIR

SAMPLE = RECORDINGS_DIR / "holistic_both_hands_47f.pose"  # pose-format v0.2, 586 points (XYZC), 47 frames at 25 fps


# ----------------------------------------------------------------------------- .pose of every version
def _sample():
    from pose_format import Pose

    raw = SAMPLE.read_bytes()
    pose = Pose.read(raw)
    header_end = raw.index(struct.pack("<fIH", pose.body.fps, len(pose.body.data), 1))  # the v0.2 body counts follow the header
    return raw[:header_end], pose


def _with_version(header: bytes, version: float) -> bytes:
    return struct.pack("<f", version) + header[4:]


def pose_v0_1(path, frames=None, declared=None, cut_to=None):
    """The sample as a version 0.1 file (16-bit fps and frames; all frames' data, then all confidences)."""
    header, pose = _sample()
    data = np.ma.getdata(pose.body.data).astype("<f4")[: frames]
    conf = np.asarray(pose.body.confidence, dtype="<f4")[: frames]
    T = len(data)
    if cut_to is not None:  # a cut the reader cannot see from the length alone: whole frames of data and confidence
        data, conf = data[:cut_to], conf[:cut_to]
    body = struct.pack("<HHH", int(pose.body.fps), T if declared is None else declared, 1) + data.tobytes() + conf.tobytes()
    path.write_bytes(_with_version(header, 0.1) + body)
    return path


def pose_v0_0(path, frames_people=None):
    """The sample as a version 0.0 file (per frame: people, then per person an id and XYZC per point)."""
    header, pose = _sample()
    data = np.ma.getdata(pose.body.data).astype("<f4")
    conf = np.asarray(pose.body.confidence, dtype="<f4")
    people = frames_people if frames_people is not None else [1] * len(data)
    out = [struct.pack("<HH", int(pose.body.fps), len(people))]
    for t, n in enumerate(people):
        out.append(struct.pack("<H", n))
        for pid in range(n):
            xyzc = np.concatenate([data[t, 0], conf[t, 0][:, None]], axis=1)
            out.append(struct.pack("<h", pid) + xyzc.tobytes())
    path.write_bytes(_with_version(header, 0.0) + b"".join(out))
    return path


def test_every_pose_version_reads_to_the_same_demonstration(tmp_path):
    reference = load_demonstration(SAMPLE)
    for name, make in (("v01", pose_v0_1), ("v00", pose_v0_0)):
        demo = load_demonstration(make(tmp_path / f"{name}.pose"))
        assert len(demo) == len(reference) == 47
        np.testing.assert_allclose(demo.arm_positions, reference.arm_positions, atol=1e-6, err_msg=name)
        np.testing.assert_array_equal(demo.finger_mask, reference.finger_mask)


def test_v0_0_with_empty_frames_declaring_a_huge_body_is_refused_unparsed(tmp_path):
    """65,535 frames without a person: 2 bytes each in the file, a whole frame each in pose-format's arrays (over 6 GiB)."""
    path = pose_v0_0(tmp_path / "bomb.pose", frames_people=[0] * 65535)
    assert path.stat().st_size < 200_000
    with pytest.raises(DemonstrationError, match=r"declares 65535 frames .* more than the 256.0 MiB a .pose file may hold") as err:
        load_demonstration(path)
    assert "bomb.pose" in str(err.value)


@pytest.mark.parametrize("people, match", [
    ([1] * 46 + [65], "frame 46 declares 65 people, more than 64"),
    ([1] * 46 + [2], "truncated: the file ends inside frame 46"),
])
def test_v0_0_frames_are_walked(people, match, tmp_path):
    path = tmp_path / "walk.pose"
    raw = pose_v0_0(path, frames_people=[1] * 47).read_bytes()
    # rewrite the last frame's people count without adding its people: the walk must notice
    last = len(raw) - (2 + 2 + 586 * 16)
    path.write_bytes(raw[:last] + struct.pack("<H", people[-1]) + raw[last + 2:])
    with pytest.raises(DemonstrationError, match=match):
        load_demonstration(path)


def test_v0_0_with_bytes_after_its_frames(tmp_path):
    path = pose_v0_0(tmp_path / "pad.pose")
    path.write_bytes(path.read_bytes() + b"\0" * 8)
    with pytest.raises(DemonstrationError, match="padded: 8 bytes follow the 47 frames"):
        load_demonstration(path)


def test_v0_1_cut_between_frames_is_an_error_not_fewer_frames(tmp_path):
    """The issue's case: a v0.1 file cut to whole frames read as a shorter recording, exit 0."""
    path = pose_v0_1(tmp_path / "cut.pose", cut_to=20)
    with pytest.raises(DemonstrationError, match="truncated or padded: the header declares 47 frames, the body holds 20"):
        load_demonstration(path)


def test_v0_1_cut_inside_a_frame(tmp_path):
    path = pose_v0_1(tmp_path / "cut.pose")
    path.write_bytes(path.read_bytes()[:-100])
    with pytest.raises(DemonstrationError, match="truncated or padded"):
        load_demonstration(path)


def test_an_unknown_pose_version_is_refused(tmp_path):
    header, _ = _sample()
    path = tmp_path / "v5.pose"
    path.write_bytes(_with_version(SAMPLE.read_bytes(), 0.5))
    with pytest.raises(DemonstrationError, match=r"unsupported .pose version 0.5"):
        load_demonstration(path)


def test_the_pose_limit_is_stated_in_the_message(tmp_path):
    path = tmp_path / "big.pose"
    with open(path, "wb") as f:
        f.truncate(MAX_POSE_BYTES + 1)
    with pytest.raises(DemonstrationError, match=r"256.0 MiB, more than the 256.0 MiB a .pose file may be"):
        load_demonstration(path)


# ----------------------------------------------------------------------------- .h5: only the file named
def h5_file(path, **special):
    """A one-group file in the authors' layout; ``special`` maps a dataset to how it is stored."""
    with h5py.File(path, "w") as f:
        g = f.create_group("word")
        for key, value in authors_arms(10).items():
            how = special.get(key)
            if how is None:
                g[key] = value
            elif how == "virtual":
                src = path.with_name("source.h5")
                with h5py.File(src, "w") as s:
                    s["x"] = value
                layout = h5py.VirtualLayout(shape=value.shape, dtype="f8")
                layout[:] = h5py.VirtualSource(str(src), "x", shape=value.shape)
                g.create_virtual_dataset(key, layout)
            elif how == "external":
                raw = path.with_name("raw.bin")
                raw.write_bytes(value.astype("<f8").tobytes())
                g.create_dataset(key, shape=value.shape, dtype="<f8", external=[(str(raw), 0, value.nbytes)])
            elif how == "huge chunks":
                g.create_dataset(key, data=value, maxshape=(None, 3), chunks=(1 << 22, 3))
            elif how == "gzip":
                g.create_dataset(key, data=value, chunks=(5, 3), compression="gzip", shuffle=True, fletcher32=True)
    return path


def test_an_h5_file_reads(tmp_path):
    demo = load_demonstration(h5_file(tmp_path / "ok.h5", l_up_pos="gzip"))
    assert len(demo) == 10


@pytest.mark.parametrize("how, match", [
    ("virtual", "is a virtual dataset: its data lives in other files, which are not read"),
    ("external", "is stored in an external raw file, which is not read"),
    ("huge chunks", r"has chunks of 96.0 MiB, more than 64.0 MiB"),
])
def test_h5_storage_outside_the_file_is_refused(how, match, tmp_path, monkeypatch):
    path = h5_file(tmp_path / "x.h5", r_hd_pos=how)
    seen = []
    import builtins

    real_open = builtins.open
    monkeypatch.setattr(builtins, "open", lambda f, *a, **k: seen.append(str(f)) or real_open(f, *a, **k))
    with pytest.raises(DemonstrationError, match=match) as err:
        load_demonstration(path)
    assert "x.h5" in str(err.value) and "word/r_hd_pos" in str(err.value)
    assert not [s for s in seen if "source.h5" in s or "raw.bin" in s]


def test_h5_virtual_dataset_pointing_at_a_system_file(tmp_path):
    """The issue's case: a virtual dataset whose source is /etc/passwd-like; nothing of it reaches the demonstration."""
    secret = tmp_path / "secret.h5"
    with h5py.File(secret, "w") as s:
        s["x"] = np.full((10, 3), 7.0)
    path = tmp_path / "v.h5"
    with h5py.File(path, "w") as f:
        g = f.create_group("word")
        for key, value in authors_arms(10).items():
            g[key] = value
        del g["l_hd_pos"]
        layout = h5py.VirtualLayout(shape=(10, 3), dtype="f8")
        layout[:] = h5py.VirtualSource(str(secret), "x", shape=(10, 3))
        g.create_virtual_dataset("l_hd_pos", layout)
    with pytest.raises(DemonstrationError, match="virtual dataset"):
        load_demonstration(path)



LOOPING_H5 = Path(__file__).resolve().parents[1] / "fuzz" / "corpus" / "h5" / "found-4939c48c205e.h5"  # make fuzz, 2026-11-27


def test_an_h5_file_libhdf5_loops_on_is_refused_after_its_cpu_time(monkeypatch):
    """A 10 kB file whose object header keeps libhdf5 looping (found by ``make fuzz``): in one process nothing could
    interrupt it; the reader's HDF5 process is stopped at its CPU-time limit and the file refused in one line."""
    monkeypatch.setattr(h5_reader, "H5_CPU_SECONDS", 2)
    with pytest.raises(DemonstrationError, match="more than 2 s of CPU time") as err:
        load_demonstration(LOOPING_H5)
    assert LOOPING_H5.name in str(err.value) and len(str(err.value).splitlines()) == 1


def test_an_h5_library_crash_is_one_line(tmp_path, monkeypatch):
    """The HDF5 process killed by a signal (as a crash of libhdf5 on a corrupt file would): one line naming the file."""
    crashing = tmp_path / "crash.py"
    crashing.write_text("import os, signal\nos.kill(os.getpid(), signal.SIGSEGV)\n")
    monkeypatch.setattr(h5_reader, "_EXTRACT", crashing)
    with pytest.raises(DemonstrationError, match=r"the HDF5 library failed on it \(signal 11\)") as err:
        load_demonstration(h5_file(tmp_path / "ok.h5"))
    assert "ok.h5" in str(err.value)


def test_the_h5_process_reads_only_the_descriptor_it_is_given(tmp_path, monkeypatch):
    """The HDF5 process gets the file the reader opened, not its name: a file swapped in under the same name after the
    reader opened it is not what is read."""
    path = h5_file(tmp_path / "x.h5")
    real = h5_reader._extract

    def swap_then_extract(handle, *args):
        (tmp_path / "other.h5").write_bytes(b"not hdf5")
        (tmp_path / "other.h5").replace(path)  # the name now holds another file
        return real(handle, *args)

    monkeypatch.setattr(h5_reader, "_extract", swap_then_extract)
    assert len(load_demonstration(path)) == 10


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**50))
def test_the_h5_process_writes_sizes_as_the_library_does(n):
    assert h5_extract.size(n) == format_size(n)

# ----------------------------------------------------------------------------- .npz: only known members, bounded inflation
def _demo_npz(path):
    from nlo_lab.corpus import corpus_clip

    return save_npz(corpus_clip("introduction_06"), path)


def _replace_member(path, name, header: bytes, payload_chunks=(), compress=zipfile.ZIP_DEFLATED):
    """Rewrite ``path`` with member ``name``.npy replaced by a raw ``header`` and payload."""
    with zipfile.ZipFile(path) as z:
        members = {n: z.read(n) for n in z.namelist() if n != name + ".npy"}
    with zipfile.ZipFile(path, "w", compress) as z:
        for n, data in members.items():
            z.writestr(n, data)
        with z.open(name + ".npy", "w", force_zip64=True) as f:
            f.write(header)
            for chunk in payload_chunks:
                f.write(chunk)


def _npy_header(shape, descr) -> bytes:
    import io

    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"shape": shape, "fortran_order": False, "descr": descr})
    return buf.getvalue()


@pytest.mark.parametrize("shape, descr, match", [
    ((47, 2, 3, 3), "<U100000", "dtype <U100000 is not allowed here"),  # the bytes-per-element bomb
    ((47, 2, 3, 3), "|V100000", r"dtype \|V100000 is not allowed here"),
    ((47, 2, 3, 3), "<c32", "dtype complex256 is not allowed here"),
    ((1 << 40,), "<f8", "declares 1099511627776 elements"),
])
def test_npz_member_declaring_more_than_it_may_hold(shape, descr, match, tmp_path):
    path = _demo_npz(tmp_path / "d.npz")
    _replace_member(path, "arm_positions", _npy_header(shape, descr), [bytes(1 << 20)])
    with pytest.raises(DemonstrationError, match=match) as err:
        load_demonstration(path)
    assert err.value.field == "arm_positions" and "d.npz" in str(err.value)


def test_npz_npy_header_of_gigabytes_is_refused_before_it_is_read(tmp_path):
    path = _demo_npz(tmp_path / "d.npz")
    _replace_member(path, "fps", b"\x93NUMPY\x02\x00" + struct.pack("<I", 0xFFFFFFF0), [bytes(1 << 20)] * 4)
    with pytest.raises(DemonstrationError, match="its header declares 4294967280 bytes, more than 10000"):
        load_demonstration(path)


def test_npz_members_inflating_beyond_the_total_are_refused(tmp_path, monkeypatch):
    """Each member within its own limit, together more than the stated total: refused before the last is inflated."""
    import nlo_lab.human.readers.npz as io_npz

    path = _demo_npz(tmp_path / "d.npz")
    monkeypatch.setattr(io_npz, "MAX_NPZ_INFLATED", 100_000)  # the sample's arrays: about 60 kB for the first four
    with pytest.raises(DemonstrationError, match=r"would inflate to more than the 97.7 KiB"):
        load_demonstration(path)


def test_npz_with_too_many_entries(tmp_path):
    path = _demo_npz(tmp_path / "d.npz")
    with zipfile.ZipFile(path, "a") as z:
        for i in range(70):
            z.writestr(f"junk{i}.npy", b"")
    with pytest.raises(DemonstrationError, match="lists 81 entries, more than the 64"):
        load_demonstration(path)


def test_npz_unknown_member_of_gigabytes_is_never_inflated(tmp_path):
    """The issue's case (RobotTrajectory.load, and the demonstration reader alike): an unknown member is skipped unread."""
    import time

    path = _demo_npz(tmp_path / "d.npz")
    with zipfile.ZipFile(path, "a", zipfile.ZIP_DEFLATED) as z, z.open("extra.npy", "w", force_zip64=True) as f:
        f.write(_npy_header((1 << 29,), "<f8"))
        for _ in range(256):
            f.write(bytes(1 << 20))  # 256 MiB of zeros: 256 kB deflated
    start = time.perf_counter()
    demo = load_demonstration(path)
    assert len(demo) == 133 and time.perf_counter() - start < 5  # inflating 256 MiB would take longer


def test_npz_member_with_more_bytes_than_declared(tmp_path):
    path = _demo_npz(tmp_path / "d.npz")
    with zipfile.ZipFile(path) as z:
        fps = z.read("fps.npy")
    _replace_member(path, "fps", fps, [b"trailing"])
    with pytest.raises(DemonstrationError, match="holds more bytes than its header declares"):
        load_demonstration(path)


# ----------------------------------------------------------------------------- videos: sizes checked before decoding
def _avi(path, w=128, h=96, frames=5):
    cv2 = pytest.importorskip("cv2")
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10, (w, h))
    for i in range(frames):
        writer.write(np.full((h, w, 3), 40 * i, np.uint8))
    writer.release()
    return path


def test_a_video_announcing_8192_by_8192_is_refused_before_decoding(tmp_path, monkeypatch):
    """The issue's case (over 6 GiB): refused from the container's announcement, no frame decoded."""
    from nlo_lab.human.readers import video as video_frames

    path = _avi(tmp_path / "huge.avi", 8192, 8192, frames=1)
    decoded = []
    monkeypatch.setattr(video_frames.VideoFrames, "__iter__", lambda self: decoded.append(1) or iter(()))
    with pytest.raises(DemonstrationError, match=r"announces frames of 8192x8192 pixels, more than nlo_lab reads") as err:
        load_demonstration(path)
    assert "huge.avi" in str(err.value) and not decoded


def test_a_video_announcing_a_million_frames_is_refused(tmp_path):
    path = _avi(tmp_path / "long.avi")
    raw = bytearray(path.read_bytes())
    at = raw.index(b"strh") + 16 + 24  # the stream header's dwLength
    struct.pack_into("<I", raw, at, 1_000_000)
    path.write_bytes(bytes(raw))
    with pytest.raises(DemonstrationError, match="announces 1000000 frames, more than the 432000"):
        load_demonstration(path)


def test_a_frame_of_another_size_than_announced_is_an_error(tmp_path):
    from nlo_lab.human.readers.video import VideoFrames, VideoInfo

    path = _avi(tmp_path / "v.avi", 128, 96)
    frames = VideoFrames(path, VideoInfo(10.0, 64, 48, 5))
    with pytest.raises(DemonstrationError, match="frame 0 decodes to 128x96 pixels, not the 64x48 its container announces"):
        list(frames)
    assert len(list(VideoFrames(path, VideoInfo(10.0, 128, 96, 5)))) == 5


def test_shown_frames_are_bounded(tmp_path, monkeypatch):
    from nlo_lab.human.readers import video as video_frames

    path = _avi(tmp_path / "v.avi", 128, 96, frames=5)
    assert video_frames.read_video_frames(path, max_side=None).shape == (5, 96, 128, 3)
    monkeypatch.setattr(video_frames, "MAX_SHOWN_BYTES", 4 * 128 * 96 * 3)
    with pytest.raises(DemonstrationError, match=r"5 frames of 36.0 KiB would take more than the 144.0 KiB"):
        video_frames.read_video_frames(path, max_side=None)


def test_estimation_frames_and_workers_fit_in_memory():
    from nlo_lab.human.readers.video import IN_FLIGHT_BYTES, MAX_ESTIMATION_SIDE, SEGMENT_FRAMES, VideoInfo, _workers_in_memory

    for w, h in ((640, 480), (1920, 1080), (3840, 2160), (7680, 4320)):
        workers = _workers_in_memory(VideoInfo(30.0, w, h, 100))
        s = min(1.0, MAX_ESTIMATION_SIDE / max(w, h))
        segment = SEGMENT_FRAMES * 3 * round(w * s) * round(h * s)
        assert workers >= 1 and (workers + 2) * segment <= max(IN_FLIGHT_BYTES, 3 * segment)
    assert _workers_in_memory(VideoInfo(30.0, 7680, 4320, 100)) == _workers_in_memory(VideoInfo(30.0, 1920, 1080, 100)) == 3
