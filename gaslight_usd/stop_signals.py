"""SIGTERM stops a long command as Ctrl-C does.

Render farms and batch schedulers stop a job with SIGTERM. Python's default is to die
on the spot: an atomic write's temporary file stays behind and nothing says why the
job ended. Raised as KeyboardInterrupt instead, the command unwinds like Ctrl-C:
temporary files are removed, the fit's checkpoint is kept for a resume, and the CLI
exits with 130 ("interrupted").

pycolmap installs glog's failure handler for SIGTERM when it is imported: a stage
that imports it later would then die on SIGTERM with a stack dump and no cleanup.
Importing it first (``preload_pycolmap``) lets this handler win.

A signal can land while C code runs a Python callback (numpy comparing structured
arrays calls ``np.result_type``): the KeyboardInterrupt raised there is swallowed and
replaced by the C code's own error, and a scene stopped by SIGTERM was reported
"failed: TypeError". ``stop_requested`` says a stop signal came, so that callers can
take any error raised after it for the interruption it is.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from typing import Any

STOP_SIGNALS = (signal.SIGTERM, signal.SIGINT)
_stop = threading.Event()


def stop_requested() -> bool:
    """Whether a stop signal reached this process's handler."""
    return _stop.is_set()


def as_interrupt(exc: BaseException) -> BaseException:
    """``exc`` itself, or a KeyboardInterrupt chained to it when a stop signal came
    first (the error is then the stop's, raised where C code swallowed it)."""
    if isinstance(exc, KeyboardInterrupt) or not stop_requested():
        return exc
    interrupt = KeyboardInterrupt()
    interrupt.__cause__ = exc
    return interrupt


def raise_interrupt_once(signum: int, frame: Any) -> None:
    """SIGTERM or SIGINT: stop as Ctrl-C does (KeyboardInterrupt), once; a second
    signal while the stop is under way is ignored so that cleanup is not cut short."""
    _stop.set()
    for sig in STOP_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)
    raise KeyboardInterrupt


def claim_stop_signals(preload_pycolmap: bool = True) -> None:
    """SIGTERM and SIGINT raise KeyboardInterrupt (once) from here on (main thread only)."""
    if preload_pycolmap:
        with contextlib.suppress(ImportError):
            import pycolmap  # noqa: F401
    _stop.clear()
    for sig in STOP_SIGNALS:
        signal.signal(sig, raise_interrupt_once)


@contextlib.contextmanager
def stop_on_signals(preload_pycolmap: bool = True) -> Iterator[None]:
    """:func:`claim_stop_signals` for the block, the previous handlers restored after;
    outside the main thread (where handlers cannot be set) it does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.getsignal(s) for s in STOP_SIGNALS}
    claim_stop_signals(preload_pycolmap)
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
