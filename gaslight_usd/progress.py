"""Progress on long work, on stderr, throttled; silent with ``-q``.

A count line reads ``[label] done/total extras, eta N s``: the ETA is the mean
time per unit so far times the units left, shown once a stage has run for a
few seconds (before that it is noise). Labels nest (``[scene 2/5 fit]``), so
the lines of scenes running side by side in a batch say whose they are.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

ETA_AFTER_SECONDS = 3.0


def format_seconds(seconds: float) -> str:
    """``42 s``, ``3 min 05 s``, ``1 h 02 min``."""
    seconds = max(0, int(round(seconds)))
    if seconds < 60:
        return f"{seconds} s"
    minutes, secs = divmod(seconds, 60)
    if minutes < 60:
        return f"{minutes} min {secs:02d} s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes:02d} min"


class Progress:
    def __init__(self, label: str = "", quiet: bool = False, stream: TextIO | None = None,
                 interval: float = 1.0):
        self.label = label
        self.quiet = quiet
        self.stream = stream or sys.stderr
        self.interval = interval
        self._last = 0.0
        self._start: tuple[float, int, int | None] | None = None  # (time, done, total)

    def child(self, label: str) -> Progress:
        """A Progress for one part of this work; its lines carry both labels."""
        joined = f"{self.label} {label}" if self.label else label
        return Progress(joined, self.quiet, self.stream, self.interval)

    def message(self, text: str) -> None:
        if not self.quiet:
            prefix = f"[{self.label}] " if self.label else ""
            print(prefix + text, file=self.stream, flush=True)

    def eta(self, done: int, total: int | None, now: float | None = None) -> float | None:
        """Seconds left at the rate since the first update of this count, or None."""
        now = time.monotonic() if now is None else now
        start = self._start
        if start is None or start[2] != total or done < start[1]:
            self._start = (now, done, total)
            return None
        elapsed, units = now - start[0], done - start[1]
        if total is None or units <= 0 or done >= total or elapsed < ETA_AFTER_SECONDS:
            return None
        return elapsed / units * (total - done)

    def update(self, done: int, total: int | None = None, force: bool = False, **info) -> None:
        """Report ``done`` of ``total`` with optional values (loss=..., splats=...)."""
        now = time.monotonic()
        left = self.eta(done, total, now)
        last = total is not None and done >= total
        if self.quiet or (not force and not last and now - self._last < self.interval):
            return
        self._last = now
        count = f"{done}/{total}" if total else str(done)
        extras = " ".join(
            f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in info.items()
        )
        eta = f", eta {format_seconds(left)}" if left is not None else ""
        self.message(f"{count} {extras}".rstrip() + eta)
