"""Progress of a batch on stderr."""

from __future__ import annotations

import math
import sys
import time
from typing import Mapping


class BatchProgress:
    """'batch NAME [#####     ] 37/120 done, 35 ok, 1 failed, 1 crashed, ~3m10s left' on stderr.

    Redrawn in place on a terminal; in logs a line every 10 % of the cases (at most one a minute apart
    otherwise)."""

    def __init__(self, name: str, stream=None) -> None:
        self.name = name
        self.stream = stream or sys.stderr
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.t0 = time.perf_counter()
        self._last_step = -1
        self._last_line = 0.0

    def __call__(self, state: Mapping) -> None:
        total, done, skipped = state["total"], state["done"], state["skipped"]
        ran = done - skipped
        elapsed = time.perf_counter() - self.t0
        left = elapsed / ran * (total - done) if ran else float("nan")
        bar = "#" * int(25 * done / total) if total else ""
        text = (
            f"batch {self.name} [{bar:<25}] {done}/{total} done, {state['ok']} ok, {state['failed']} failed, "
            f"{state['crashed']} crashed, {_duration(elapsed)} elapsed, ~{_duration(left)} left"
        )
        if self.tty:
            self.stream.write("\r" + text + ("\n" if done == total else ""))
        else:
            step = int(10 * done / total) if total else 10
            if step == self._last_step and done != total and time.monotonic() - self._last_line < 60:
                return
            self._last_step, self._last_line = step, time.monotonic()
            self.stream.write(text + "\n")
        self.stream.flush()


def _duration(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "?"
    seconds = int(round(seconds))
    if seconds < 60:
        return f"{seconds}s"
    if seconds < 3600:
        return f"{seconds // 60}m{seconds % 60:02d}s"
    return f"{seconds // 3600}h{seconds % 3600 // 60:02d}m"
