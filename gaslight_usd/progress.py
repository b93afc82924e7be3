"""Progress on long work, on stderr, throttled; silent with ``-q``."""

from __future__ import annotations

import sys
import time
from typing import TextIO


class Progress:
    def __init__(self, label: str = "", quiet: bool = False, stream: TextIO | None = None,
                 interval: float = 1.0):
        self.label = label
        self.quiet = quiet
        self.stream = stream or sys.stderr
        self.interval = interval
        self._last = 0.0

    def child(self, label: str) -> Progress:
        return Progress(label, self.quiet, self.stream, self.interval)

    def message(self, text: str) -> None:
        if not self.quiet:
            prefix = f"[{self.label}] " if self.label else ""
            print(prefix + text, file=self.stream, flush=True)

    def update(self, done: int, total: int | None = None, force: bool = False, **info) -> None:
        """Report ``done`` of ``total`` with optional values (loss=..., splats=...)."""
        now = time.monotonic()
        last = total is not None and done >= total
        if self.quiet or (not force and not last and now - self._last < self.interval):
            return
        self._last = now
        count = f"{done}/{total}" if total else str(done)
        extras = " ".join(
            f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in info.items()
        )
        self.message(f"{count} {extras}".rstrip())
