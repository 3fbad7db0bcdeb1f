"""``nlo-lab robot init URDF --out SPEC.json`` and ``nlo-lab robot check SPEC.json``: your own robot.

``init`` drafts a complete spec from any URDF with two arms (:func:`nlo_lab.robot.spec_draft.draft_spec`)
and prints what it chose; ``check`` loads a spec against its URDF and prints its summary
(:mod:`nlo_lab.robot.spec_check`). Problems end as one line and exit status 2
(:mod:`nlo_lab.cli.run_guard`); warnings (a velocity limit the URDF does not give) print once each.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from nlo_lab.cli.flags import UsageError

__all__ = ["add_parser", "run", "parse_links", "parse_fingers"]


def parse_links(text: str) -> tuple[str, str, str]:
    """``SHOULDER,ELBOW,WRIST`` -> three link names (argparse type of ``--left-arm``)."""
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != 3 or not all(parts):
        raise argparse.ArgumentTypeError(f"expected SHOULDER,ELBOW,WRIST (three link names), got {text!r}")
    return parts[0], parts[1], parts[2]


def parse_fingers(text: str) -> dict[str, str]:
    """``thumb=LINK,index=LINK,...`` -> {finger: tip link}; ``none`` -> {} (argparse type of ``--left-hand``)."""
    if text.strip().lower() == "none":
        return {}
    out = {}
    for item in text.split(","):
        finger, sep, link = (x.strip() for x in item.partition("="))
        if not sep or not finger or not link:
            raise argparse.ArgumentTypeError(f"expected thumb=LINK,index=LINK,... (or none), got {text!r}")
        if finger in out:
            raise argparse.ArgumentTypeError(f"the {finger} finger is named twice in {text!r}")
        out[finger] = link
    return out


def add_parser(subparsers) -> None:
    """Add ``robot init`` and ``robot check`` to the command line's sub-parsers."""
    p = subparsers.add_parser("robot", help="draft a robot spec from a URDF (init), or check a spec (check)")
    sub = p.add_subparsers(dest="robot_command", required=True, parser_class=type(p))
    init = sub.add_parser("init", help="draft a complete robot spec .json from any URDF with two arms")
    init.add_argument("urdf", metavar="URDF", help="the robot's .urdf (a xacro file must be expanded first)")
    init.add_argument("--out", required=True, metavar="SPEC.json", help="the spec to write (its urdf field is relative to it)")
    for side in ("left", "right"):
        init.add_argument(f"--{side}-arm", type=parse_links, default=None, metavar="SHOULDER,ELBOW,WRIST",
                          help=f"the {side} arm's link names (default: found from the tree and the names)")
        init.add_argument(f"--{side}-hand", type=parse_fingers, default=None, metavar="thumb=LINK,index=LINK,...",
                          help="fingertip links of any of thumb, index, middle, ring, little (or pinky); none: no fingers "
                               "(default: found by name below the wrist)")
    init.add_argument("--base", default=None, metavar="LINK", help="the link the arms hang from (default: where the two arms meet)")
    init.add_argument("--name", default=None, help="the robot's name (default: the URDF's)")
    init.add_argument("--srdf", default=None, metavar="SRDF", help="the robot's SRDF: the link pairs it disables are not checked")
    init.add_argument("--force", action="store_true", help="replace SPEC.json if it exists")
    init.add_argument("--quiet", action="store_true", help="no progress bar (shown only when stderr is a terminal), no warnings")
    check = sub.add_parser("check", help="check a robot spec against its URDF and print a summary")
    check.add_argument("spec", metavar="SPEC.json", help="a robot spec .json (or a bundled robot's name)")
    check.add_argument("--quiet", action="store_true", help="no warnings")


def _init(args) -> int:
    from nlo_lab.atomic_files import atomic_write_bytes
    from nlo_lab.robot.spec import spec_text
    from nlo_lab.robot.spec_draft import draft_spec

    out = Path(args.out)
    if out.suffix.lower() != ".json":
        raise UsageError(f"nlo-lab robot init: --out must name a .json file, got {args.out!r}")
    if out.exists() and not args.force:
        raise UsageError(f"nlo-lab robot init: {args.out!r} exists (--force replaces it)")
    if not out.resolve().parent.is_dir():
        raise UsageError(f"nlo-lab robot init: --out: the folder {str(out.parent)!r} does not exist")
    draft = draft_spec(args.urdf, out, left_arm=args.left_arm, right_arm=args.right_arm, left_hand=args.left_hand,
                       right_hand=args.right_hand, base=args.base, name=args.name, srdf=args.srdf,
                       progress=not args.quiet and sys.stderr.isatty())
    for message in draft.warnings:
        warnings.warn(message, stacklevel=2)
    atomic_write_bytes(out, spec_text(draft.spec).encode("utf-8"))
    print("\n".join(draft.summary()))
    return 0


def _check(args) -> int:
    from nlo_lab.robot.spec_check import check_spec, spec_summary

    print("\n".join(spec_summary(check_spec(args.spec))))
    return 0


def run(args) -> int:
    """Run ``nlo-lab robot init`` or ``nlo-lab robot check``; returns the exit status."""
    return _init(args) if args.robot_command == "init" else _check(args)
