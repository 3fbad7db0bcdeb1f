"""msgpack of meshcat commands with floats in single precision, fast for animations.

The viewer page stores each command msgpack-packed. An animation holds one key
``{"time": t, "value": [x, y, z(, w)]}`` per frame and track: millions of floats for
a long recording, which ``umsgpack`` (pure Python) packs at about a microsecond
each. :func:`packb_single` produces the same bytes as
``umsgpack.packb(obj, force_float_precision="single")`` (tested equal), but packs
runs of such keys with numpy. Set :data:`FAST` to False to use umsgpack alone.
"""

from __future__ import annotations

import numpy as np
import umsgpack

__all__ = ["FAST", "packb_single"]

FAST = True  # the numpy path for lists of animation keys; False: umsgpack for everything


def packb_single(obj) -> bytes:
    """``umsgpack.packb(obj, force_float_precision="single")``, faster for animation keys."""
    if not FAST:
        return umsgpack.packb(obj, force_float_precision="single")
    out: list[bytes] = []
    _pack(obj, out)
    return b"".join(out)


def _leaf(obj) -> bytes:
    return umsgpack.packb(obj, force_float_precision="single")


def _container_head(n: int, fix: int, b16: int, b32: int) -> bytes:
    if n < 16:
        return bytes([fix | n])
    if n < 2**16:
        return bytes([b16]) + n.to_bytes(2, "big")
    return bytes([b32]) + n.to_bytes(4, "big")


def _pack(obj, out: list[bytes]) -> None:
    if type(obj) is dict:
        out.append(_container_head(len(obj), 0x80, 0xDE, 0xDF))
        for key, value in obj.items():
            _pack(key, out)
            _pack(value, out)
    elif type(obj) in (list, tuple):
        keys = _as_keys(obj)
        out.append(_container_head(len(obj), 0x90, 0xDC, 0xDD))
        if keys is not None:
            out.append(_pack_keys(*keys))
        else:
            for item in obj:
                _pack(item, out)
    else:
        out.append(_leaf(obj))


def _as_keys(items) -> tuple[np.ndarray, np.ndarray] | None:
    """``(times (K,), values (K, N))`` when ``items`` are animation keys of float vectors, else None.

    The times are all ints (frame numbers) or all floats (a retimed trajectory's, see
    :func:`nlo_lab.viz.tracks.set_key_times`); ``times.dtype`` says which.
    """
    if len(items) < 2:
        return None
    first = items[0]
    if type(first) is not dict or list(first) != ["time", "value"] or type(first["value"]) is not list:
        return None
    n = len(first["value"])
    time_type = type(first["time"])
    if not 0 < n < 16 or time_type not in (int, float):
        return None
    times, values = [], []
    for key in items:
        if type(key) is not dict or list(key) != ["time", "value"]:
            return None
        t, v = key["time"], key["value"]
        if type(t) is not time_type or (time_type is int and not 0 <= t < 2**32):
            return None
        if type(v) is not list or len(v) != n or any(type(x) is not float for x in v):
            return None
        times.append(t)
        values.append(v)
    return np.array(times, dtype=np.int64 if time_type is int else np.float64), np.array(values, dtype=np.float64)


_HEAD = np.frombuffer(b"\x82\xa4time", dtype=np.uint8)  # fixmap(2), "time"


def _float32s(values: np.ndarray) -> np.ndarray:
    """``(K, N, 5)`` bytes: each float as msgpack's float 32 (tag 0xCA, big-endian)."""
    k, n = values.shape
    out = np.empty((k, n, 5), dtype=np.uint8)
    out[:, :, 0] = 0xCA
    out[:, :, 1:] = values.astype(">f4").view(np.uint8).reshape(k, n, 4)
    return out


def _pack_keys(times: np.ndarray, values: np.ndarray) -> bytes:
    """The keys' bytes, as umsgpack writes them: ints in their shortest form, floats as float32."""
    k, n = values.shape
    middle = np.frombuffer(b"\xa5value" + bytes([0x90 | n]), dtype=np.uint8)  # "value", fixarray(n)
    floats = _float32s(values)
    if times.dtype.kind == "f":  # float times: float32 like the values, one block
        block = np.concatenate([np.broadcast_to(_HEAD, (k, len(_HEAD))), _float32s(times[:, None]).reshape(k, 5),
                                np.broadcast_to(middle, (k, len(middle))), floats.reshape(k, 5 * n)], axis=1)
        return block.tobytes()
    # the time's encoding depends on its size: positive fixint, uint8, uint16, uint32
    kind = np.searchsorted(np.array([128, 256, 2**16]), times, side="right")
    blocks = []
    start = 0
    while start < k:
        stop = start + int(np.argmax(kind[start:] != kind[start])) if (kind[start:] != kind[start]).any() else k
        t = times[start:stop]
        c = int(kind[start])
        if c == 0:
            tb = t.astype(np.uint8)[:, None]
        else:
            tag, width = ((0xCC, "u1"), (0xCD, ">u2"), (0xCE, ">u4"))[c - 1]
            raw = t.astype(width).view(np.uint8).reshape(len(t), -1)
            tb = np.concatenate([np.full((len(t), 1), tag, dtype=np.uint8), raw], axis=1)
        m = len(t)
        blocks.append(np.concatenate([
            np.broadcast_to(_HEAD, (m, len(_HEAD))),
            tb,
            np.broadcast_to(middle, (m, len(middle))),
            floats[start:stop].reshape(m, 5 * n),
        ], axis=1))
        start = stop
    return b"".join(b.tobytes() for b in blocks)
