"""Errors a user sees: one line, naming the file and what is wrong.

Exit codes (documented in ``gaslight2usd --help``):

====  ==========================================================
0     success
1     the work failed (a stage could not finish)
2     usage error, or a subcommand/method that is not built yet
3     bad input (unreadable file, unknown colour space, empty folder, NaN...)
130   interrupted (Ctrl-C); outputs already finished stay, nothing half-written
====  ==========================================================
"""

from __future__ import annotations

from pathlib import Path

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2
EXIT_BAD_INPUT = 3
EXIT_INTERRUPTED = 130


class GaslightError(Exception):
    """An error meant for the user: ``str(err)`` is a single line."""

    exit_code = EXIT_FAILED

    def __init__(self, message: str, path: str | Path | None = None):
        super().__init__(message)
        self.message = message.strip().replace("\n", " ")
        self.path = Path(path) if path is not None else None

    def __str__(self) -> str:
        return f"{self.path}: {self.message}" if self.path is not None else self.message


class InputError(GaslightError):
    """The input is wrong: a missing/unreadable file, bad values, an unknown name."""

    exit_code = EXIT_BAD_INPUT


class UsageError(GaslightError):
    """The request cannot be met as asked (e.g. no converter chain links input to output)."""

    exit_code = EXIT_USAGE


class FitDiverged(GaslightError):
    """The optimisation produced NaN or infinite values: stopped before they reach a file."""


class NotBuiltYet(GaslightError):
    """A subcommand or method that the project has not built yet."""

    exit_code = EXIT_USAGE
