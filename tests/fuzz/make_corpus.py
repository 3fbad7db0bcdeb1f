"""Write the fuzz corpus: the hostile cases of issues 16 and 25 as small files, and valid controls.

    python tests/fuzz/make_corpus.py [--out tests/fuzz/corpus]

Each file's name says what it holds and what nlo_lab must do with it:

- ``ok-*``: a valid input; it must be read (the command line exits 0);
- ``bad-*``: a hostile or broken input; it must be refused with one line naming the file
  (exit status 2), within the memory ceiling, quickly;
- ``found-*``: an input the fuzzer (``tests/fuzz/fuzz.py --grow``) found; either is fine,
  a crash, a traceback or a hang is not.

The folders are the reader they go to: ``pose/``, ``npz/``, ``h5/``, ``video/``
(recordings: ``nlo-lab retarget FILE``), ``robot/`` (a robot spec folder: ``--robot
FOLDER/spec.json``), ``checkpoint/`` (``load_checkpoint``), ``trajectory/``
(``RobotTrajectory.load``). Files are kept small (the largest some 150 kB): a bomb here
is a few bytes that claim gigabytes. Cases that cannot be files in a repository (a FIFO,
a symlink to /dev/zero, a socket, a sparse 64 GiB file) are made at test time
(``tests/fuzz/targets.py``). The committed corpus is this script's output; run it again
after changing a case.
"""

from __future__ import annotations

import argparse
import io
import json
import shutil
import struct
import zipfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
SAMPLE_POSE = REPO / "assets" / "recordings" / "holistic_both_hands_47f.pose"
SAMPLE_VIDEO = REPO / "assets" / "recordings" / "signer_webcam_58f.mp4"
ROBOTS = REPO / "assets" / "robots"
CHECKPOINTS = REPO / "assets" / "checkpoints"
KEEP = ("POSE_LANDMARKS", "LEFT_HAND_LANDMARKS", "RIGHT_HAND_LANDMARKS", "POSE_WORLD_LANDMARKS")


# ----------------------------------------------------------------------------- .pose
def small_pose(frames: int = 24):
    """The bundled sample without its face mesh, its first ``frames`` frames: 108 points, about 40 kB."""
    from pose_format import Pose
    from pose_format.numpy import NumPyPoseBody

    pose = Pose.read(SAMPLE_POSE.read_bytes()).get_components(list(KEEP))
    body = NumPyPoseBody(pose.body.fps, pose.body.data[:frames], pose.body.confidence[:frames])
    return Pose(pose.header, body)


def pose_bytes(pose) -> bytes:
    buf = io.BytesIO()
    pose.write(buf)
    return buf.getvalue()


def _body_offset(raw: bytes) -> int:
    from pose_format.pose_header import PoseHeader
    from pose_format.utils.reader import BufferReader

    reader = BufferReader(raw)
    PoseHeader.read(reader)
    return reader.read_offset


def _v01(pose, declared: int | None = None, keep: int | None = None) -> bytes:
    raw = pose_bytes(pose)
    at = _body_offset(raw)
    data = np.ma.getdata(pose.body.data).astype("<f4")
    conf = np.asarray(pose.body.confidence, dtype="<f4")
    T = len(data)
    data, conf = data[:keep], conf[:keep]
    body = struct.pack("<HHH", int(pose.body.fps), T if declared is None else declared, data.shape[1]) + data.tobytes() + conf.tobytes()
    return struct.pack("<f", 0.1) + raw[4:at] + body


def _v00(pose, people_per_frame=None) -> bytes:
    raw = pose_bytes(pose)
    at = _body_offset(raw)
    data = np.ma.getdata(pose.body.data).astype("<f4")
    conf = np.asarray(pose.body.confidence, dtype="<f4")
    people = [1] * len(data) if people_per_frame is None else people_per_frame
    out = [struct.pack("<HH", int(pose.body.fps), len(people))]
    for t, n in enumerate(people):
        out.append(struct.pack("<H", n))
        for pid in range(n):
            row = data[min(t, len(data) - 1), 0]
            c = conf[min(t, len(data) - 1), 0]
            out.append(struct.pack("<h", pid) + np.concatenate([row, c[:, None]], axis=1).tobytes())
    return struct.pack("<f", 0.0) + raw[4:at] + b"".join(out)


def _with_counts(raw: bytes, frames=None, people=None, fps=None) -> bytes:
    at = _body_offset(raw)
    old_fps, old_frames, old_people = struct.unpack_from("<fIH", raw, at)
    data = bytearray(raw)
    struct.pack_into("<fIH", data, at, old_fps if fps is None else fps, old_frames if frames is None else frames,
                     old_people if people is None else people)
    return bytes(data)


def pose_cases() -> dict[str, bytes]:
    from pose_format import Pose
    from pose_format.numpy import NumPyPoseBody

    pose = small_pose()
    raw = pose_bytes(pose)
    cases = {
        "ok-v02.pose": raw,
        "ok-v01.pose": _v01(pose),
        "ok-v00.pose": _v00(pose),
        "bad-v00-65535-frames-without-a-person.pose": _v00(pose, [0] * 65535),  # over 6 GiB in pose-format's arrays
        "bad-v00-frame-declares-65535-people.pose": _v00(pose, [1] * 5 + [0])[:-2] + struct.pack("<H", 65535),
        "bad-v01-cut-at-12-of-24-frames.pose": _v01(pose, keep=12),  # read as 12 frames, exit 0, before
        "bad-v02-declares-4e9-frames.pose": _with_counts(raw, frames=4_000_000_000),
        "bad-v02-declares-65535-people.pose": _with_counts(raw, people=65535),
        "bad-v02-cut-in-the-body.pose": raw[: len(raw) - 1000],
        "bad-v02-bytes-after-the-body.pose": raw + b"\0" * 64,
        "bad-v02-fps-nan.pose": _with_counts(raw, fps=float("nan")),
        "bad-v02-fps-3e38.pose": _with_counts(raw, fps=3e38),
        "bad-unknown-version.pose": struct.pack("<f", 7.5) + raw[4:],
        "bad-header-only.pose": raw[: _body_offset(raw)],
        "bad-text.pose": b"this is not a pose file\n" * 20,
        "bad-version-only.pose": raw[:4],
    }
    data = np.ma.getdata(pose.body.data).copy()
    conf = np.asarray(pose.body.confidence).copy()
    world = sum(len(c.points) for c in pose.header.components[:3])
    zero = data.copy()
    zero[:, :, world:] = 0.0  # every world landmark at zero (ZeroDivisionError in issue 16)
    cases["bad-world-landmarks-all-zero.pose"] = pose_bytes(Pose(pose.header, NumPyPoseBody(pose.body.fps, zero, conf)))
    huge = data.copy()
    huge[:, :, :world] = np.clip(huge[:, :, :world].astype(np.float64) * 1e36, -3e38, 3e38)  # about 3e38 (exit 0 in issue 25)
    huge[:, :, world:] = 3e38
    cases["bad-coordinates-3e38.pose"] = pose_bytes(Pose(pose.header, NumPyPoseBody(pose.body.fps, huge, conf)))
    nan = data.copy()
    nan[3, 0, 11] = np.nan  # LEFT_SHOULDER, observed
    cases["bad-nan-landmark.pose"] = pose_bytes(Pose(pose.header, NumPyPoseBody(pose.body.fps, nan, conf)))
    hidden = conf.copy()
    hidden[:, :, 11] = 0.0  # the left shoulder never seen
    cases["bad-left-shoulder-never-seen.pose"] = pose_bytes(Pose(pose.header, NumPyPoseBody(pose.body.fps, data, hidden)))
    header = pose.header
    named = type(header)(header.version, header.dimensions, [
        type(c)(c.name, [p if p != "LEFT_ELBOW" else "LEFT_ELBOW\x1b[2J\nINJECTED" for p in c.points], c.limbs, c.colors, c.format)
        for c in header.components])
    cases["bad-point-name-with-terminal-codes.pose"] = pose_bytes(Pose(named, NumPyPoseBody(pose.body.fps, data, conf)))
    return cases


# ----------------------------------------------------------------------------- .npz
def small_demo():
    from nlo_lab.corpus import corpus_clip
    from nlo_lab.human import Demonstration

    d = corpus_clip("introduction_06")
    keys = ("arm_positions", "arm_mask", "wrist_rotations", "wrist_mask", "finger_positions", "finger_mask")
    return Demonstration(d.fps, *(getattr(d, k)[:20].copy() for k in keys), name="introduction_06", meta={"source": "corpus"})


def _npz(members: dict[str, bytes | np.ndarray], compression=zipfile.ZIP_DEFLATED) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression) as z:
        for name, value in members.items():
            if isinstance(value, np.ndarray):
                b = io.BytesIO()
                np.save(b, value, allow_pickle=True)
                value = b.getvalue()
            z.writestr(name if "." in name else name + ".npy", value)
    return buf.getvalue()


def _demo_members(**override) -> dict:
    d = small_demo()
    content = {"format": np.array("nlo_lab.demonstration"), "format_version": np.array(1), "fps": np.array(d.fps),
               "name": np.array(d.name), "meta_json": np.array(json.dumps(d.meta))}
    for key in ("arm_positions", "arm_mask", "wrist_rotations", "wrist_mask", "finger_positions", "finger_mask"):
        content[key] = getattr(d, key)
    content.update(override)
    return {k: v for k, v in content.items() if v is not None}


def _npy_header(shape, descr, version=1) -> bytes:
    b = io.BytesIO()
    header = {"shape": shape, "fortran_order": False, "descr": descr}
    (np.lib.format.write_array_header_1_0 if version == 1 else np.lib.format.write_array_header_2_0)(b, header)
    return b.getvalue()


def _deflated_zeros(header: bytes, megabytes: int) -> bytes:
    """A member of ``header`` followed by ``megabytes`` MiB of zeros, deflated (about 1 kB per MiB)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z, z.open("x.npy", "w", force_zip64=True) as f:
        f.write(header)
        chunk = bytes(1 << 20)
        for _ in range(megabytes):
            f.write(chunk)
    return buf.getvalue()


def npz_cases() -> dict[str, bytes]:
    arm = small_demo().arm_positions
    far = arm.copy()
    far[4, 1, 2] = [3e38, -3e38, 3e38]
    masked = small_demo()
    masked.arm_mask[:, 0] = False
    masked_arms = masked.arm_positions.copy()
    masked_arms[:, 0] = np.nan

    class Boom:
        def __reduce__(self):
            return (print, ("pickled code ran",))

    cases = {
        "ok-demonstration.npz": _npz(_demo_members()),
        "bad-coordinates-3e38.npz": _npz(_demo_members(arm_positions=far)),
        "bad-left-arm-fully-masked.npz": _npz(_demo_members(arm_positions=masked_arms, arm_mask=masked.arm_mask)),
        "bad-fps-text.npz": _npz(_demo_members(fps=np.array("25"))),
        "bad-fps-1e300.npz": _npz(_demo_members(fps=np.array(1e300))),
        "bad-fps-complex.npz": _npz(_demo_members(fps=np.array(25 + 1j))),
        "bad-format-version-text.npz": _npz(_demo_members(format_version=np.array("abc"))),
        "bad-meta-nested-100000-deep.npz": _npz(_demo_members(meta_json=np.array('{"a": ' + "[" * 100_000 + "]" * 100_000 + "}"))),
        "bad-missing-fps.npz": _npz(_demo_members(fps=None)),
        "bad-pickle-in-a-member.npz": _npz(_demo_members(name=np.array([Boom()], dtype=object))),
        "bad-100000-bytes-per-element.npz": _npz({**_demo_members(arm_positions=None),
                                                   "arm_positions.npy": _npy_header((20, 2, 3, 3), "<U25000") + bytes(1000)}),
        "bad-npy-header-of-4-gib.npz": _npz({**_demo_members(fps=None), "fps.npy": b"\x93NUMPY\x02\x00" + struct.pack("<I", 0xFFFFFFF0)}),
        "bad-declares-1e12-elements.npz": _npz({**_demo_members(arm_positions=None),
                                                "arm_positions.npy": _npy_header((10**12,), "<f8") + bytes(64)}),
        "bad-too-many-entries.npz": _npz({**_demo_members(), **{f"junk{i}.npy": b"" for i in range(100)}}),
        "bad-truncated.npz": _npz(_demo_members())[:-200],
        "bad-npy-renamed-to-npz.npz": _npy_header((3,), "<f8") + bytes(24),
        "bad-text.npz": b"PK but not really a zip file" * 10,
    }
    # an unknown member that would inflate to 64 MiB: skipped unread, so the archive reads
    members = _demo_members()
    inner = zipfile.ZipFile(io.BytesIO(_deflated_zeros(_npy_header((8 << 20,), "<f8"), 64)))
    members["extra.npy"] = inner.read("x.npy")
    cases["ok-unknown-member-of-64-mib-skipped.npz"] = _npz(members)
    return cases


# ----------------------------------------------------------------------------- .h5
def _h5(build) -> bytes:
    import tempfile

    import h5py

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "x.h5"
        with h5py.File(path, "w", libver="earliest") as f:
            build(f)
        return path.read_bytes()


def authors_arms(T=12):
    t = np.arange(T)[:, None]
    out = {}
    for s, sign in (("l", 1.0), ("r", -1.0)):
        sh = np.array([0.0, 0.17 * sign, 1.4]) + 0 * t
        el = sh + np.array([0.05, 0.05 * sign, -0.25]) + 0.01 * np.sin(t)
        wr = el + np.array([0.25, 0.0, 0.05]) + 0 * t
        out.update({f"{s}_up_pos": sh, f"{s}_fr_pos": el, f"{s}_hd_pos": wr})
    return out


def _group(f, name="word", skip=(), **extra):
    g = f.create_group(name)
    for key, value in authors_arms().items():
        if key not in skip:
            g[key] = value
    for key, value in extra.items():
        g[key] = value
    return g


def h5_cases() -> dict[str, bytes]:
    import h5py

    def virtual(f):
        g = _group(f, skip=("l_hd_pos",))
        layout = h5py.VirtualLayout(shape=(12, 3), dtype="f8")
        layout[:] = h5py.VirtualSource("/etc/passwd", "x", shape=(12, 3))  # read /etc/passwd as HDF5, in issue 25
        g.create_virtual_dataset("l_hd_pos", layout, fillvalue=0.5)

    def external(f):
        g = _group(f, skip=("l_hd_pos",))
        g.create_dataset("l_hd_pos", shape=(12, 3), dtype="<f8", external=[("/etc/passwd", 0, 288)])

    def external_link(f):
        _group(f)
        f["elsewhere"] = h5py.ExternalLink("/etc/passwd", "/x")

    def dangling(f):
        _group(f)
        f["gone"] = h5py.SoftLink("/nowhere")

    def huge_rows(f):
        g = _group(f, skip=("l_up_pos",))
        g.create_dataset("l_up_pos", shape=(500_000_000, 3), dtype="f8", chunks=(1024, 3), compression="gzip")

    def huge_chunks(f):
        g = _group(f, skip=("r_hd_pos",))
        g.create_dataset("r_hd_pos", data=authors_arms()["r_hd_pos"], maxshape=(None, 3), chunks=(1 << 22, 3), compression="gzip")

    def fps(value):
        def build(f):
            _group(f).attrs["fps"] = value
        return build

    def complex_data(f):
        g = _group(f, skip=("l_fr_pos",))
        g["l_fr_pos"] = authors_arms()["l_fr_pos"] + 1j

    def escaped_name(f):
        g = _group(f, name="word\x1b[31m\nINJECTED", skip=("l_up_pos",))
        g["l_up_pos"] = np.full((12, 3), np.nan)

    def far(f):
        arms = authors_arms()
        g = f.create_group("word")
        for key, value in arms.items():
            g[key] = value * (1e36 if key == "l_hd_pos" else 1.0)

    return {
        "ok-authors-layout.h5": _h5(lambda f: _group(f)),
        "bad-virtual-dataset-of-etc-passwd.h5": _h5(virtual),
        "bad-external-raw-storage-etc-passwd.h5": _h5(external),
        "bad-external-link-at-the-root.h5": _h5(lambda f: (external_link(f), f.__delitem__("word"))),
        "bad-dangling-link-at-the-root.h5": _h5(lambda f: (dangling(f), f.__delitem__("word"))),
        "bad-declares-500m-rows.h5": _h5(huge_rows),
        "bad-chunks-of-96-mib.h5": _h5(huge_chunks),
        "bad-fps-1e300.h5": _h5(fps(1e300)),
        "bad-fps-text.h5": _h5(fps("25")),
        "bad-fps-array-of-60000.h5": _h5(fps(np.zeros(60_000, dtype="u1"))),
        "bad-complex-positions.h5": _h5(complex_data),
        "bad-group-name-with-terminal-codes.h5": _h5(escaped_name),
        "bad-coordinates-1e36.h5": _h5(far),
        "bad-no-group.h5": _h5(lambda f: f.create_dataset("x", data=np.zeros(3))),
        "bad-text.h5": b"\x89HDF\r\n\x1a\n" + b"not really" * 30,
    }


# ----------------------------------------------------------------------------- videos
def _avi(w=64, h=48, frames=4, value=lambda i: 40 * i) -> bytes:
    import tempfile

    import cv2

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "x.avi"
        writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10, (w, h))
        for i in range(frames):
            writer.write(np.full((h, w, 3), value(i), np.uint8))
        writer.release()
        return path.read_bytes()


def video_cases() -> dict[str, bytes]:
    black = _avi()
    long = bytearray(black)
    struct.pack_into("<I", long, long.index(b"strh") + 16 + 24, 1_000_000)  # the stream header's frame count
    sample = SAMPLE_VIDEO.read_bytes()
    return {
        "bad-no-person-in-any-frame.avi": black,
        "bad-announces-a-million-frames.avi": bytes(long),
        "bad-truncated-sample.mp4": sample[: len(sample) // 5],
        "bad-text-named-mp4.mp4": b"not a video at all\n" * 10,
        "bad-pose-file-named-mp4.mp4": pose_bytes(small_pose(4)),
        "bad-riff-without-frames.avi": b"RIFF\x10\x00\x00\x00AVI LIST\x04\x00\x00\x00hdrl",
    }


# ----------------------------------------------------------------------------- robot specs, URDFs, checkpoints
def robot_cases() -> dict[str, dict[str, bytes]]:
    """Folders: ``spec.json`` (the robot given to ``--robot``) and what it names."""
    spec = json.loads((ROBOTS / "nao.json").read_text())
    urdf = (ROBOTS / spec["urdf"]).read_bytes()

    def folder(spec_change=None, urdf_bytes=urdf, spec_bytes=None):
        s = dict(spec, urdf="robot.urdf")
        if spec_change:
            s.update(spec_change)
        return {"spec.json": spec_bytes if spec_bytes is not None else json.dumps(s).encode(), "robot.urdf": urdf_bytes}

    xxe = b'<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY x SYSTEM "file:///etc/passwd">]>\n' + urdf.replace(
        b'name="nao"', b'name="&x;"', 1)
    laughs = (b'<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY a "aaaaaaaaaa">' +
              b"".join(f'<!ENTITY {chr(98 + i)} "{("&" + chr(97 + i) + ";") * 10}">'.encode() for i in range(8)) +
              b"]>\n" + urdf.replace(b'name="nao"', b'name="&i;"', 1))
    return {
        "ok-nao-copy": folder(),
        "bad-spec-binary": folder(spec_bytes=bytes(range(256)) * 4),
        "bad-spec-margin-text": folder({"collision_margin": "abc"}),
        "bad-spec-nested-20000-deep": folder(spec_bytes=b'{"a": ' + b"[" * 20_000 + b"]" * 20_000 + b"}"),
        "bad-spec-urdf-outside": folder({"urdf": "/etc/passwd"}),
        "bad-urdf-xxe": folder(urdf_bytes=xxe),
        "bad-urdf-billion-laughs": folder(urdf_bytes=laughs),
        "bad-urdf-truncated": folder(urdf_bytes=urdf[: len(urdf) // 2]),
    }


def checkpoint_cases() -> dict[str, bytes]:
    """Small crafted checkpoints (the valid control is the shipped ``nao.pt``, not copied here)."""
    import torch

    def saved(obj) -> bytes:
        buf = io.BytesIO()
        torch.save(obj, buf)
        return buf.getvalue()

    small = {"format_version": 2, "robot": "nao", "joint_names": 5, "model_config": {}, "state_dict": {"w": torch.zeros(4)}}
    zf = zipfile.ZipFile(io.BytesIO(saved(small)))
    deflated = io.BytesIO()
    with zipfile.ZipFile(deflated, "w", zipfile.ZIP_DEFLATED) as z:
        for info in zf.infolist():
            z.writestr(info.filename, zf.read(info.filename))

    class Boom:
        def __reduce__(self):
            return (print, ("pickled code ran",))

    return {
        "bad-deflated-records.pt": deflated.getvalue(),
        "bad-pickled-code.pt": saved({"format_version": 2, "robot": "nao", "x": Boom()}),
        "bad-joint-names-a-number.pt": saved(small),
        "bad-robot-pepper.pt": saved({**small, "robot": "pepper"}),
        "bad-truncated.pt": saved(small)[:300],
        "bad-text.pt": b"not a checkpoint\n" * 10,
    }


def trajectory_cases() -> dict[str, bytes]:
    good = io.BytesIO()
    np.savez(good, format_version=np.int64(2), robot=np.str_("nao"), joint_names=np.array(["a", "b"]),
             angles=np.zeros((3, 2)), fps=np.float64(10.0), time=np.array([0.0, 0.1, 0.2]))
    members = dict(zipfile.ZipFile(io.BytesIO(good.getvalue())).read(n) and (n, zipfile.ZipFile(io.BytesIO(good.getvalue())).read(n))
                   for n in zipfile.ZipFile(io.BytesIO(good.getvalue())).namelist())
    inner = zipfile.ZipFile(io.BytesIO(_deflated_zeros(_npy_header((8 << 20,), "<f8"), 64)))
    bomb = _npz({**members, "unknown.npy": inner.read("x.npy")})
    return {
        "ok-trajectory.npz": good.getvalue(),
        "ok-unknown-member-of-64-mib-skipped.npz": bomb,
        "bad-joint-names-scalar.npz": _npz({**members, "joint_names.npy": _npy_header((), "<U1") + "a".encode("utf-32-le")}),
        "bad-angles-header-of-4-gib.npz": _npz({**members, "angles.npy": b"\x93NUMPY\x02\x00" + struct.pack("<I", 0xFFFFFFF0)}),
        "bad-text.json": b"{not json",
        "bad-nested-20000-deep.json": b'{"a": ' + b"[" * 20_000 + b"]" * 20_000 + b"}",
    }


def write(out: Path) -> list[Path]:
    """Write every case below ``out`` (replacing the ``ok-``/``bad-`` files; ``found-`` files are kept)."""
    written = []
    groups = {"pose": pose_cases(), "npz": npz_cases(), "h5": h5_cases(), "video": video_cases(),
              "checkpoint": checkpoint_cases(), "trajectory": trajectory_cases()}
    for kind, cases in groups.items():
        folder = out / kind
        folder.mkdir(parents=True, exist_ok=True)
        for old in folder.glob("[ob][ka]*-*"):
            if old.is_file() and (old.name.startswith("ok-") or old.name.startswith("bad-")):
                old.unlink()
        for name, payload in cases.items():
            (folder / name).write_bytes(payload)
            written.append(folder / name)
    robots = out / "robot"
    if robots.exists():
        for old in robots.iterdir():
            if old.is_dir() and (old.name.startswith("ok-") or old.name.startswith("bad-")):
                shutil.rmtree(old)
    for name, files in robot_cases().items():
        folder = robots / name
        folder.mkdir(parents=True, exist_ok=True)
        for file, payload in files.items():
            (folder / file).write_bytes(payload)
        written.append(folder / "spec.json")
    return written


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE / "corpus")
    args = parser.parse_args()
    written = write(args.out)
    total = sum(p.stat().st_size for p in args.out.rglob("*") if p.is_file())
    print(f"wrote {len(written)} cases below {args.out} ({total / 1e6:.2f} MB in all)")


if __name__ == "__main__":
    main()
