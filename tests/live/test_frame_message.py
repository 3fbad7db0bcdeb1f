"""A frame message from the page: every malformed part is one clear FrameMessageError; a good one decodes."""

from __future__ import annotations

import io
import struct

import numpy as np
import pytest

from nlo_lab.live import MAX_FRAME_BYTES, FrameMessageError, decode_frame_message, encode_frame


def _jpeg(w=64, h=48) -> bytes:
    img = np.zeros((h, w, 3), np.uint8)
    img[:, : w // 2] = (200, 30, 30)
    return encode_frame(img, 480, 0.8)


def test_a_good_frame_decodes():
    msg = decode_frame_message({"type": "frame", "seq": 3, "t": 1.25}, [memoryview(_jpeg())])
    assert (msg.seq, msg.t, msg.image.shape, msg.image.dtype) == (3, 1.25, (48, 64, 3), np.uint8)
    assert abs(int(msg.image[10, 5, 0]) - 200) < 12 and msg.image[10, 60, 0] < 20  # the colours, through JPEG


def test_encode_frame_shrinks_to_the_stated_size():
    from PIL import Image

    img = np.zeros((720, 540, 3), np.uint8)
    data = encode_frame(img, 480, 0.8)
    assert Image.open(io.BytesIO(data)).size == (360, 480)


def _png() -> bytes:
    from PIL import Image

    buffer = io.BytesIO()
    Image.new("RGB", (8, 8)).save(buffer, format="PNG")
    return buffer.getvalue()


def _huge_header(side: int = 60000) -> bytes:
    """A JPEG whose header announces ``side`` x ``side`` pixels (a few hundred bytes)."""
    data = bytearray(_jpeg())
    at = data.find(b"\xff\xc0")
    struct.pack_into(">HH", data, at + 5, side, side)
    return bytes(data)


@pytest.mark.parametrize("content, buffers, needle", [
    ("frame", [b""], "not an object"),
    ({"seq": "3", "t": 1.0}, [b"x"], "seq must be a whole number"),
    ({"seq": True, "t": 1.0}, [b"x"], "seq must be a whole number"),
    ({"seq": 1, "t": float("nan")}, [b"x"], "frame 1 from the page: t must be a finite time"),
    ({"seq": 1, "t": "now"}, [b"x"], "t must be a finite time"),
    ({"seq": 1, "t": 1.0}, [], "expected one binary buffer"),
    ({"seq": 1, "t": 1.0}, None, "expected one binary buffer"),
    ({"seq": 1, "t": 1.0}, [b"a", b"b"], "expected one binary buffer"),
    ({"seq": 1, "t": 1.0}, [b""], "the JPEG buffer is empty"),
    ({"seq": 1, "t": 1.0}, [b"\xff\xd8\xff" + bytes(MAX_FRAME_BYTES)], "more than"),
    ({"seq": 1, "t": 1.0}, ["png"], "not a JPEG image"),
    ({"seq": 1, "t": 1.0}, ["truncated"], "does not decode"),
    ({"seq": 1, "t": 1.0}, ["huge"], "more than 4096 pixels a side"),
    ({"seq": 1, "t": 1.0}, ["big"], "more than 4096 a side"),
])
def test_a_malformed_message_is_one_clear_error(content, buffers, needle):
    if buffers and buffers[0] in ("png", "truncated", "huge", "big"):
        buffers = [{"png": _png, "truncated": lambda: _jpeg()[:200], "huge": _huge_header, "big": lambda: _huge_header(5000)}[buffers[0]]()]
    with pytest.raises(FrameMessageError) as info:
        decode_frame_message(content, buffers)
    text = str(info.value)
    assert needle in text and "\n" not in text and text.count("from the page") == 1, text
