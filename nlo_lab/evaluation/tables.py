"""The evaluation's two outputs: the JSON contract object and Table I.

:func:`to_json` gives exactly :data:`JSON_KEYS` per method (``nlo-lab evaluate --json``,
docs/ARCHITECTURE.md); :func:`format_table` the paper's Table I as text or markdown.
"""

from __future__ import annotations

import math

from nlo_lab.evaluation.scores import Evaluation, SequenceScore

__all__ = ["JSON_KEYS", "COLLISION_MARK", "to_json", "format_table"]

JSON_KEYS = (
    "frechet_m", "per_sequence", "collision_sequences", "limit_violations", "seconds",
    "velocity_violations", "max_joint_speed_ratio", "slowdown", "depth",
)
COLLISION_MARK = "*"


def _num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def to_json(ev: Evaluation) -> dict:
    """The command line's contract object (exactly :data:`JSON_KEYS` per method)."""
    return {
        "methods": {
            m: {
                "frechet_m": _num(ev.mean(m)),
                "per_sequence": {s: _num(ev.scores[m][s].frechet_m) for s in ev.sequences},
                "collision_sequences": ev.collision_sequences(m),
                "limit_violations": int(ev.total(m, "limit_violations")),
                "seconds": round(ev.total(m, "seconds"), 4),
                "velocity_violations": int(ev.total(m, "velocity_violations")),
                "max_joint_speed_ratio": _num(max(s.max_joint_speed_ratio for s in ev.scores[m].values())),
                "slowdown": _num(max(s.slowdown for s in ev.scores[m].values())),
                "depth": "/".join(sorted({s.depth for s in ev.scores[m].values()})),
            }
            for m in ev.methods
        }
    }


def format_table(ev: Evaluation, *, markdown: bool = False) -> str:
    """Table I: Fréchet distance [m] per sequence (rows) and method (columns).

    ``*`` marks a sequence where the method's motion has a self-collision frame;
    then the mean row, velocity/acceleration error means, sequences with
    collisions, limit violations and the summed wall time.
    """
    methods = ev.methods
    w = max(12, *(len(m) for m in methods))
    first = max(8, *(len(s) for s in ev.sequences), len("acc. err [m/s²]"))

    def cell(score: SequenceScore) -> str:
        mark = COLLISION_MARK if score.collision_frames > 0 else ""
        return f"{score.frechet_m:.4f}{mark}"

    rows = [[s] + [cell(ev.scores[m][s]) for m in methods] for s in ev.sequences]
    summary = [
        ["mean [m]"] + [f"{ev.mean(m):.4f}" for m in methods],
        ["vel. err [m/s]"] + [f"{ev.mean(m, 'velocity_error'):.3f}" for m in methods],
        ["acc. err [m/s²]"] + [f"{ev.mean(m, 'acceleration_error'):.2f}" for m in methods],
        ["objective"] + [f"{ev.mean(m, 'objective'):.2f}" for m in methods],
        ["collision seq."] + [str(ev.collision_sequences(m)) for m in methods],
        ["limit viol."] + [str(int(ev.total(m, "limit_violations"))) for m in methods],
        ["velocity viol."] + [str(int(ev.total(m, "velocity_violations"))) for m in methods],
        ["max speed/limit"] + [f"{max(s.max_joint_speed_ratio for s in ev.scores[m].values()):.2f}" for m in methods],
        ["max slowdown"] + [f"{max(s.slowdown for s in ev.scores[m].values()):.2f}" for m in methods],
        ["wall time [s]"] + [f"{ev.total(m, 'seconds'):.2f}" for m in methods],
    ]
    header = ["sequence"] + methods
    if markdown:
        lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
        lines += ["| **" + r[0] + "** | " + " | ".join(r[1:]) + " |" for r in summary]
        return "\n".join(lines)
    fmt = lambda r: f"{r[0]:<{first}} " + " ".join(f"{c:>{w}}" for c in r[1:])  # noqa: E731
    rule = "-" * (first + (w + 1) * len(methods))
    lines = [f"Fréchet distance [m] on {ev.robot}, mean of wrist and elbow; {COLLISION_MARK} = self-collision in the sequence", fmt(header), rule]
    lines += [fmt(r) for r in rows] + [rule] + [fmt(r) for r in summary]
    return "\n".join(lines)
