"""Old import path of the video view (:mod:`nlo_lab.lab.video_view`), kept for notebooks copied by earlier versions."""

from nlo_lab.lab.video_view import *  # noqa: F403
from nlo_lab.lab.video_view import __all__  # noqa: F401
