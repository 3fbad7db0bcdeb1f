"""Reading a ``.npz`` archive within bounds: only the members asked for, each checked before it is inflated.

``numpy.load`` trusts an archive: it lists every member, reads any member it is asked for
whole, and its ``.npy`` header may announce gigabytes. A crafted archive of 2 MB can
inflate to 4 GiB. :func:`read_npz_members` reads archives of the package's own formats
(a demonstration, :func:`nlo_lab.human.save_npz`; a robot trajectory,
``RobotTrajectory.save_npz``) by a stated layout instead:

- the file is checked first (:mod:`nlo_lab.files`: a regular file of at most ``max_bytes``);
- the zip directory may list at most :data:`MAX_MEMBERS` entries (a directory of millions
  of entries is itself a memory bomb) and is read from the end-of-directory record first;
- only the members of the layout are opened; the others are never read;
- each member's ``.npy`` header (at most :data:`MAX_NPY_HEADER` bytes) is parsed before
  its data: the dtype must be of the kinds the layout allows (never Python objects, so no
  pickle), at most 8 bytes per number or the layout's text length, the element count at
  most the layout's, and all members together at most ``max_inflated`` bytes;
- exactly the declared bytes are inflated; a member that ends early is truncated.

Every problem is one ``error(message, path=path, field=member)`` (the caller's class).
"""

from __future__ import annotations

import ast
import struct
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nlo_lab.errors import NloLabError
from nlo_lab.files import format_size, open_input

__all__ = ["MAX_MEMBERS", "MAX_NPY_HEADER", "Member", "read_npz_members"]

MAX_MEMBERS = 64  # entries in an archive's zip directory; ours hold 6-11
MAX_NPY_HEADER = 10_000  # bytes of a member's .npy header (numpy's own default limit)
_EOCD = struct.Struct("<4s4H2LH")  # end of central directory record
_MAGIC = b"\x93NUMPY"


@dataclass(frozen=True)
class Member:
    """What one member of an archive may hold.

    Attributes:
        kinds: the dtype kinds allowed (``"f"``, ``"iu"``, ``"U"``, ``"b"`` ...).
        ndim: the number of dimensions it must have (0: a scalar; None: any).
        max_elements: the most elements it may have.
        max_chars: for text (kind ``"U"``): the most characters per element.
    """

    kinds: str
    ndim: int | None = 0
    max_elements: int = 1
    max_chars: int = 0


def _member_count(f, size: int) -> int:
    """Entries of the zip directory, from the end-of-directory record (without parsing the directory)."""
    tail_len = min(size, _EOCD.size + 0xFFFF)  # the record sits within the last 64 kB (its comment comes after)
    f.seek(size - tail_len)
    tail = f.read(tail_len)
    at = tail.rfind(b"PK\x05\x06")
    if at < 0 or at + _EOCD.size > len(tail):
        return -1
    _sig, _disk, _start_disk, _here, total, _cd_size, _cd_offset, _comment = _EOCD.unpack_from(tail, at)
    return total


def _read_exact(fh, n: int) -> bytes:
    data = fh.read(n)
    if len(data) != n:
        raise EOFError("truncated")
    return data


def _npy_header(fh) -> tuple[tuple[int, ...], bool, np.dtype]:
    """A member's shape, order and dtype, its header length checked before the header is read."""
    magic = _read_exact(fh, 8)
    if magic[:6] != _MAGIC:
        raise ValueError("not a .npy array (no NUMPY magic)")
    major = magic[6]
    if major not in (1, 2, 3):
        raise ValueError(f"unsupported .npy version {major}.{magic[7]}")
    length_format = "<H" if major == 1 else "<I"
    (length,) = struct.unpack(length_format, _read_exact(fh, struct.calcsize(length_format)))
    if length > MAX_NPY_HEADER:
        raise ValueError(f"its header declares {length} bytes, more than {MAX_NPY_HEADER}")
    text = _read_exact(fh, length).decode("latin1" if major < 3 else "utf8")
    header = ast.literal_eval(text)  # a dict of literals; never code
    if not isinstance(header, dict) or set(header) != {"descr", "fortran_order", "shape"}:
        raise ValueError("its header is not a .npy header")
    shape, fortran = header["shape"], header["fortran_order"]
    if not (isinstance(shape, tuple) and all(isinstance(n, int) and n >= 0 for n in shape) and len(shape) <= 8):
        raise ValueError(f"its header declares a bad shape {shape!r}")
    if not isinstance(fortran, bool):
        raise ValueError("its header declares a bad order")
    dtype = np.lib.format.descr_to_dtype(header["descr"])
    return shape, fortran, dtype


def read_npz_members(path, layout: dict[str, Member], *, kind: str, max_bytes: int, max_inflated: int,
                     error: type[NloLabError]) -> dict[str, np.ndarray]:
    """The members of ``layout`` present in the archive ``path``, each checked before it is inflated.

    Args:
        path: the ``.npz`` file.
        layout: member name (without ``.npy``) -> :class:`Member`; other members are never read.
        kind: what the file holds, for the messages (``"demonstration archive"``).
        max_bytes: the largest file accepted.
        max_inflated: the most bytes all members read may inflate to together.
        error: the exception class, called as ``error(message, path=path[, field=member])``.

    Returns:
        ``{name: array}`` of the layout's members found (missing ones are the caller's to judge).

    Raises:
        error: not a regular file, too large, not a zip archive, too many entries, a member
            of a kind, size or shape the layout does not allow, Python objects, truncated data.
    """
    path = Path(path)
    out: dict[str, np.ndarray] = {}
    with open_input(path, kind=kind, max_bytes=max_bytes, error=error) as f:
        size = f.seek(0, 2)
        count = _member_count(f, size)
        if count < 0:
            raise error(f"not a readable .npz archive (no zip directory): not a {kind}", path=path)
        if count > MAX_MEMBERS:
            raise error(f"the archive lists {count} entries, more than the {MAX_MEMBERS} a {kind} may have", path=path)
        f.seek(0)
        total = 0
        try:
            with zipfile.ZipFile(f) as zf:
                names = {info.filename for info in zf.infolist()}
                for key, member in layout.items():
                    if key + ".npy" not in names:
                        continue
                    with zf.open(key + ".npy") as fh:
                        array, nbytes = _read_member(fh, key, member, path, error, max_inflated - total, max_inflated)
                    total += nbytes
                    out[key] = array
        except NloLabError:
            raise
        except (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError, NotImplementedError, RuntimeError) as err:
            raise error(f"not a readable .npz archive ({type(err).__name__}: {err})", path=path) from None
    return out


def _read_member(fh, key: str, member: Member, path: Path, error, budget: int, max_inflated: int) -> tuple[np.ndarray, int]:
    try:
        shape, fortran, dtype = _npy_header(fh)
    except (ValueError, EOFError, SyntaxError, TypeError, MemoryError, RecursionError) as err:
        raise error(f"not a readable array ({err})", path=path, field=key) from None
    if dtype.hasobject:
        raise error("holds Python objects (pickles are refused)", path=path, field=key)
    if dtype.kind not in member.kinds or dtype.fields is not None or dtype.subdtype is not None:
        raise error(f"dtype {dtype} is not allowed here", path=path, field=key)
    if dtype.kind == "U":
        if dtype.itemsize // 4 > member.max_chars:
            raise error(f"text of {dtype.itemsize // 4} characters is too long (at most {member.max_chars})", path=path, field=key)
    elif dtype.itemsize > 8:
        raise error(f"dtype {dtype} has {dtype.itemsize} bytes per number, more than 8", path=path, field=key)
    if member.ndim is not None and len(shape) != member.ndim:
        raise error(f"must be a scalar, got shape {shape}" if member.ndim == 0 else
                    f"must have {member.ndim} dimension{'s' if member.ndim > 1 else ''}, got shape {shape}", path=path, field=key)
    count = 1
    for n in shape:
        count *= n  # Python integers: no overflow
    if count > member.max_elements:
        raise error(f"declares {count} elements (shape {shape}), more than the {member.max_elements} allowed",
                    path=path, field=key)
    nbytes = count * dtype.itemsize
    if nbytes > budget:
        raise error(f"the members read would inflate to more than the {format_size(max_inflated)} a file of this kind holds",
                    path=path, field=key)
    raw = fh.read(nbytes)
    if len(raw) != nbytes:
        raise error("truncated array", path=path, field=key)
    if fh.read(1):  # also lets zipfile check the member's CRC
        raise error("holds more bytes than its header declares", path=path, field=key)
    return np.frombuffer(raw, dtype=dtype).reshape(shape, order="F" if fortran else "C").copy(), nbytes
