"""Points on the command line (``--at X,Y,Z``), negative coordinates included.

argparse takes any token that starts with ``-`` for an option unless it looks
like a plain negative number, so ``--at -1.2,1.35,-0.58`` failed with "expected
one argument" and users had to write ``--at=-1.2,...``. :func:`attach_point_values`
joins such a value to its option before argparse sees the command line.
"""

from __future__ import annotations

import argparse
import math
import re

# Options whose value is a point (or a list of numbers) and may start with "-".
POINT_OPTIONS = ("--at",)
_NUMBER_LIST = re.compile(r"^-(\d|\.\d)[0-9eE.,+\-\s]*$")


def parse_point(text: str) -> tuple[float, float, float]:
    """``"X,Y,Z"`` as three finite floats (an argparse ``type``)."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"expected X,Y,Z (three numbers), got {text!r}")
    return values  # type: ignore[return-value]


def attach_point_values(argv: list[str]) -> list[str]:
    """``[..., "--at", "-1,2,3"]`` -> ``[..., "--at=-1,2,3"]``; other tokens unchanged."""
    out: list[str] = []
    i = 0
    while i < len(argv):
        token = argv[i]
        following = argv[i + 1] if i + 1 < len(argv) else None
        if token in POINT_OPTIONS and following is not None and _NUMBER_LIST.match(following):
            out.append(f"{token}={following}")
            i += 2
            continue
        out.append(token)
        i += 1
    return out


def positive_int(text: str) -> int:
    """A whole number >= 1 (an argparse ``type`` for counts such as --budget)."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}")
    return value
