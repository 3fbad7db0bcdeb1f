"""The old import path of :func:`retarget`: it lives in :mod:`nlo_lab.inference`.

Kept because the README of earlier versions and learners' copied notebooks import
``nlo_lab.retarget.retarget``.
"""

from nlo_lab.inference import CHUNK_FRAMES, RetargetConfig, RetargetResult, retarget, summary

__all__ = ["CHUNK_FRAMES", "RetargetConfig", "RetargetResult", "retarget", "summary"]
