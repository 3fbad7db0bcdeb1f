"""The batch's progress on stderr: done, failed, rate and time left; a bar on a terminal, plain lines in a log."""

from __future__ import annotations

import io
import re

import pytest

from nlo_lab.batch import progress as progress_module
from nlo_lab.batch.progress import Progress, format_seconds


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_the_time_left_reads_naturally():
    assert [format_seconds(s) for s in (0, 42.4, 185, 7620, -3)] == ["0 s", "42 s", "3 min 05 s", "2 h 07 min", "0 s"]


def test_a_log_gets_plain_lines_with_done_failed_rate_and_time_left(monkeypatch):
    clock = iter(range(0, 1000, 10))  # each reading of the clock is 10 s after the last
    monkeypatch.setattr(progress_module.time, "monotonic", lambda: next(clock))
    log = io.StringIO()
    bar = Progress(4, True, skipped=2, stream=log)
    assert log.getvalue() == ""  # nothing before the start (the workers still load the model)
    bar.start()
    bar.update(False)
    bar.update(True)
    bar.close()
    lines = log.getvalue().splitlines()
    assert lines[0] == "nlo-lab: batch: 4 inputs to run, 2 settled without running"
    # 1 done 30 s after the start: 0.03 inputs/s, 3 left in 90 s; the closing line adds the run's time
    assert lines[1:] == ["nlo-lab: batch: 1/4 done, 0 failed, 0.03 inputs/s, 1 min 30 s left",
                         "nlo-lab: batch: 2/4 done, 1 failed, 0.03 inputs/s, 1 min 00 s left",
                         "nlo-lab: batch: 2/4 done, 1 failed, 0.03 inputs/s, 1 min 10 s left in 1 min 20 s"]
    assert "\r" not in log.getvalue() and len(lines) == 4


def test_a_terminal_gets_a_bar(monkeypatch):
    term = Terminal()
    bar = Progress(3, True, stream=term)
    bar.start()
    bar.update(False)
    bar.update(True)
    bar.write("nlo-lab: error: bad.pose: not a .pose file")
    bar.close()
    assert "nlo-lab: error: bad.pose: not a .pose file\n" in term.getvalue()  # above the bar
    final = [part for part in term.getvalue().replace("\n", "\r").split("\r") if part.startswith("batch")][-1]
    assert re.search(r"2/3 done, 1 failed \[[\d:]+<[\d:?]+, .*input/s\]", final), final  # elapsed<left, rate


@pytest.mark.parametrize("show, total", [(False, 3), (True, 0)])
def test_quiet_or_nothing_to_run_shows_nothing(show, total):
    log = Terminal()
    bar = Progress(total, show, stream=log)
    bar.start()
    bar.close()
    assert log.getvalue() == ""
