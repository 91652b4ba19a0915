"""Progress on long work: a bar on a terminal, plain log lines otherwise.

Each session's line names the file once, with what the reader repaired and the
fit's warnings (⚠) — or why it failed.  On a terminal only sessions with
something to say get a line above the bar.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO


class BatchProgress:
    """Callable for :func:`wheelcal.batch.runner.run_batch` progress events."""

    def __init__(self, stream: TextIO | None = None, width: int = 30) -> None:
        self.stream = stream or sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.width = width
        self.start = time.perf_counter()
        self.failed = 0
        self._bar_shown = False

    def __call__(self, event) -> None:
        """Show one :class:`~wheelcal.batch.runner.ProgressEvent`."""
        if event.message:
            self._line(event.message)
        if event.record is None:
            return
        record = event.record
        if not record.ok:
            self.failed += 1
            self._line(f"[{event.done}/{event.total}] FAILED {record.error}")
        elif not self.tty or record.notes:
            # On a terminal the bar stands for the plain sessions; one with notes
            # (clipped or dropped samples, warnings) still gets its line.
            fit = record.timings_s.get("fit")
            timing = f" (fit {fit:.2f} s)" if fit is not None else ""
            notes = f" — {'; '.join(record.notes)}" if record.notes else ""
            self._line(f"[{event.done}/{event.total}] ok {record.source}{timing}{notes}")
        if self.tty:
            self._bar(event.done, event.total)

    def _line(self, text: str) -> None:
        if self.tty and self._bar_shown:
            self.stream.write("\r\033[K")
        self.stream.write(text + "\n")
        self.stream.flush()
        self._bar_shown = False

    def _bar(self, done: int, total: int) -> None:
        frac = done / total if total else 1.0
        filled = round(self.width * frac)
        elapsed = time.perf_counter() - self.start
        eta = elapsed / frac - elapsed if frac > 0 else 0.0
        bar = "#" * filled + "-" * (self.width - filled)
        text = f"\r[{bar}] {done}/{total} sessions, {self.failed} failed, ETA {eta:4.0f} s"
        self.stream.write(text)
        self.stream.flush()
        self._bar_shown = True
        if done == total:
            self.stream.write("\n")
            self._bar_shown = False
