"""What a command-line fault must look like: exit status 2 and one line naming it, no traceback."""

from __future__ import annotations


def assert_one_line_error(code, err, *needles):
    """``code`` is 2 and ``err`` is one non-empty line, no traceback, holding every one of ``needles``."""
    assert code == 2
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
