"""The batch's progress on stderr: inputs done and failed, the rate, the time left.

On a terminal (or in a notebook) a tqdm bar; elsewhere (a log file, a SLURM job's output)
one plain line every :data:`LOG_INTERVAL` seconds and one at the end, since a redrawn bar
would fill a log with carriage returns.
"""

from __future__ import annotations

import sys
import time

from tqdm.auto import tqdm

__all__ = ["LOG_INTERVAL", "Progress", "format_seconds"]

LOG_INTERVAL = 10.0  # seconds between two plain progress lines


def format_seconds(seconds: float) -> str:
    """``42 s``, ``3 min 05 s``, ``2 h 07 min``."""
    seconds = max(0, int(round(seconds)))
    if seconds < 60:
        return f"{seconds} s"
    if seconds < 3600:
        return f"{seconds // 60} min {seconds % 60:02d} s"
    return f"{seconds // 3600} h {seconds % 3600 // 60:02d} min"


class Progress:
    """Counts the inputs of one run as they finish.

    Args:
        total: inputs to run.
        show: draw anything at all.
        skipped: inputs settled without running (done before, failed before on the same content, or
            unreadable; said once, at the start).
        stream: where to write (default ``sys.stderr``).

    Nothing shows before :meth:`start`.
    """

    def __init__(self, total: int, show: bool, skipped: int = 0, stream=None):
        self.total, self.done, self.failed, self.skipped = total, 0, 0, skipped
        self.stream = stream or sys.stderr
        self.started = self._logged = time.monotonic()
        self._bar = None
        self.wanted, self.show = show and total > 0, False

    def start(self) -> None:
        """Show the progress from now on (the rate counts from here)."""
        self.started = self._logged = time.monotonic()
        self.show, skipped, total = self.wanted, self.skipped, self.total
        if not self.show:
            return
        # a terminal, or a notebook's stderr (ipykernel's OutStream, which is no tty but draws a bar)
        interactive = getattr(self.stream, "isatty", lambda: False)() or type(self.stream).__module__.startswith("ipykernel")
        if interactive:
            note = f" ({skipped} settled without running)" if skipped else ""
            self._bar = tqdm(total=total, desc=f"batch{note}", unit="input", file=self.stream, dynamic_ncols=True,
                             bar_format="{desc}: {bar} {n_fmt}/{total_fmt} done{postfix} [{elapsed}<{remaining}, {rate_fmt}]")
            self._bar.set_postfix_str("0 failed")
        else:
            self._line(f"{total} inputs to run" + (f", {skipped} settled without running" if skipped else ""))

    def _line(self, text: str) -> None:
        print(f"nlo-lab: batch: {text}", file=self.stream, flush=True)

    def status(self) -> str:
        """``12/40 done, 1 failed, 0.85 inputs/s, 33 s left``."""
        elapsed = time.monotonic() - self.started
        rate = self.done / elapsed if elapsed > 0 else 0.0
        left = f", {format_seconds((self.total - self.done) / rate)} left" if rate > 0 and self.done < self.total else ""
        return f"{self.done}/{self.total} done, {self.failed} failed, {rate:.2f} inputs/s{left}"

    def update(self, failed: bool) -> None:
        self.done += 1
        self.failed += bool(failed)
        if self._bar is not None:
            self._bar.set_postfix_str(f"{self.failed} failed", refresh=False)
            self._bar.update(1)
        elif self.show and self.done < self.total and time.monotonic() - self._logged >= LOG_INTERVAL:
            self._logged = time.monotonic()
            self._line(self.status())

    def write(self, line: str) -> None:
        """A line above the bar (a failure's error line)."""
        if self._bar is not None:
            self._bar.write(line, file=self.stream)
        else:
            print(line, file=self.stream, flush=True)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None
        elif self.show:
            self._line(f"{self.status()} in {format_seconds(time.monotonic() - self.started)}")
        self.show = False
