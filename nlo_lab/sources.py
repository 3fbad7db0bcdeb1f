"""Where a demonstration comes from: a recording file, or ``demo:NAME``, a clip of the synthetic corpus.

The front door's :func:`nlo_lab.load_demonstration` and the command line's ``INPUT`` take
either. The readers (:mod:`nlo_lab.human`) know files only, and the corpus is built on them
(:mod:`nlo_lab.corpus`): this module sits after both.
"""

from __future__ import annotations

import os

from nlo_lab.corpus import corpus_clip
from nlo_lab.human import Demonstration
from nlo_lab.human import load_demonstration as load_file

__all__ = ["DEMO_PREFIX", "load_demonstration"]

DEMO_PREFIX = "demo:"  # demo:introduction_06 is the corpus clip of that name (nlo_lab.corpus.corpus_names())


def load_demonstration(source: str | os.PathLike) -> Demonstration:
    """A demonstration from a file (``.npz``, ``.pose``, ``.h5``, a video) or ``demo:NAME``.

    Args:
        source: a path, read by :func:`nlo_lab.human.load_demonstration` (the extension
            chooses the reader), or ``"demo:NAME"`` for the clip ``NAME`` of the embedded
            synthetic corpus (:func:`nlo_lab.corpus.corpus_clip`).

    Returns:
        The :class:`~nlo_lab.human.Demonstration`, in the body frame, in metres.

    Raises:
        DemonstrationError: the file cannot be read, or no clip has that name (the message
            names the file or the clip).
    """
    if isinstance(source, str) and source.startswith(DEMO_PREFIX):
        return corpus_clip(source[len(DEMO_PREFIX):])
    return load_file(source)
