"""A camera frame as it travels from the page to the kernel: one widget message with a JPEG in its buffer.

The page (``camera_view.js``) sends ``{"type": "frame", "seq": N, "t": seconds}`` with the frame's
JPEG bytes as the message's one binary buffer: the camera image shrunk so that its longer side is
at most the widget's ``frame_size`` pixels, encoded at ``jpeg_quality``. :func:`decode_frame_message`
checks every part of such a message before it decodes anything (a page is code the kernel did not
write: a modified page, a browser bug or a truncated buffer must end in one clear
:class:`FrameMessageError`, never a traceback or a huge allocation); :func:`encode_frame` makes the
same JPEG from an image in the kernel (the sample video fed through the same path).
"""

from __future__ import annotations

import io
import math
import warnings
from dataclasses import dataclass

import numpy as np

from nlo_lab.errors import NloLabError
from nlo_lab.live.retargeter import MAX_IMAGE_SIDE

__all__ = ["MAX_FRAME_BYTES", "FrameMessage", "FrameMessageError", "decode_frame_message", "encode_frame", "shrink"]

MAX_FRAME_BYTES = 4 << 20  # a JPEG frame; a 1920x1080 frame at quality 0.95 is about 1 MB
_JPEG_START = b"\xff\xd8\xff"


class FrameMessageError(NloLabError, ValueError):
    """A frame message from the page that the kernel cannot use (malformed, not a JPEG, too large)."""


@dataclass(frozen=True)
class FrameMessage:
    """One decoded camera frame: ``seq`` (the page's count), ``t`` (its capture time on the page's clock [s]),
    ``image`` ``(H, W, 3)`` RGB ``uint8``, ``size`` (the JPEG's bytes)."""

    seq: int
    t: float
    image: np.ndarray
    size: int


def _fail(seq, text: str):
    where = f"frame {seq}" if isinstance(seq, int) and not isinstance(seq, bool) else "a frame"
    raise FrameMessageError(f"{where} from the page: {text}")


def decode_frame_message(content, buffers) -> FrameMessage:
    """The frame of a page's ``"frame"`` message.

    Raises:
        FrameMessageError: one line naming what is wrong: not a dict, a ``seq`` that is not a whole
            number, a ``t`` that is not a finite number, not exactly one buffer, an empty buffer or one
            over :data:`MAX_FRAME_BYTES`, bytes that are not a JPEG or do not decode, an image larger than
            :data:`~nlo_lab.live.retargeter.MAX_IMAGE_SIDE` a side (checked from its header, before decoding).
    """
    # lazy: Pillow: only where frames are encoded or decoded
    from PIL import Image, UnidentifiedImageError

    if not isinstance(content, dict):
        _fail(None, f"the message is not an object but {type(content).__name__}")
    seq = content.get("seq")
    if isinstance(seq, bool) or not isinstance(seq, int) or seq < 0:
        _fail(None, f"seq must be a whole number >= 0, got {seq!r:.40}")
    t = content.get("t")
    if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t):
        _fail(seq, f"t must be a finite time in seconds, got {t!r:.40}")
    if buffers is None or len(buffers) != 1:
        _fail(seq, f"expected one binary buffer (the JPEG), got {0 if buffers is None else len(buffers)}")
    data = bytes(buffers[0])
    if not data:
        _fail(seq, "the JPEG buffer is empty")
    if len(data) > MAX_FRAME_BYTES:
        _fail(seq, f"the JPEG has {len(data)} bytes, more than {MAX_FRAME_BYTES}")
    if not data.startswith(_JPEG_START):
        _fail(seq, f"not a JPEG image (it starts with {data[:8].hex()})")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)  # the size is checked below, with our limit
            img = Image.open(io.BytesIO(data))
        with img:
            w, h = img.size  # from the header: nothing decoded yet
            if img.format != "JPEG":
                _fail(seq, f"not a JPEG image but {img.format}")
            if not (1 <= w <= MAX_IMAGE_SIDE and 1 <= h <= MAX_IMAGE_SIDE):
                _fail(seq, f"the image is {w}x{h} pixels, more than {MAX_IMAGE_SIDE} a side")
            image = np.asarray(img.convert("RGB"))
    except FrameMessageError:
        raise
    except Image.DecompressionBombError:
        _fail(seq, f"the image's header announces more than {MAX_IMAGE_SIDE} pixels a side")
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as err:  # PIL's faults of a damaged file
        _fail(seq, f"the JPEG does not decode ({type(err).__name__}: {str(err)[:120]})")
    return FrameMessage(seq=seq, t=float(t), image=image, size=len(data))


def shrink(image: np.ndarray, longest: int) -> np.ndarray:
    """``image`` scaled so that its longer side is at most ``longest`` pixels (as the page does before sending)."""
    # lazy: Pillow: only where frames are encoded or decoded
    from PIL import Image

    h, w = image.shape[:2]
    scale = min(1.0, longest / max(h, w))
    if scale >= 1.0:
        return image
    size = (max(1, round(w * scale)), max(1, round(h * scale)))
    return np.asarray(Image.fromarray(image).resize(size, Image.Resampling.BILINEAR))


def encode_frame(image: np.ndarray, longest: int, quality: float) -> bytes:
    """The JPEG the page would send of an RGB ``image``: shrunk to ``longest`` pixels, at ``quality`` (0..1)."""
    # lazy: Pillow: only where frames are encoded or decoded
    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(shrink(image, longest))).save(buffer, format="JPEG", quality=round(100 * quality))
    return buffer.getvalue()
