"""Checks that an output can be written, made before any work starts.

A run that fails only when it writes its first file has wasted the user's time
and, worse, reported a plain permission problem as an internal error. So every
command checks its output path first: it must not be a file where a folder is
wanted (or a folder where a file is), and the nearest folder that exists must
take a new file. The check creates and removes one hidden empty file there;
nothing else is written.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from .errors import InputError


def nearest_existing(path: Path) -> Path:
    """``path`` itself if it exists, else its closest existing ancestor."""
    path = Path(os.path.abspath(path))
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def check_output(path: str | Path, folder: bool) -> Path:
    """Raise :class:`InputError` naming ``path`` unless it can be written.

    ``folder`` says whether ``path`` is an output folder (made if missing) or
    an output file (replaced if present). Returns ``path``.
    """
    path = Path(path)
    if path.exists():
        if folder and not path.is_dir():
            raise InputError("exists and is a file; the output must be a folder", path)
        if not folder and path.is_dir():
            raise InputError("is a folder; the output must be a file name", path)
    base = nearest_existing(path if folder else path.parent)
    if not base.is_dir():
        raise InputError(f"cannot be created: {base} is a file, not a folder", path)
    try:
        handle, probe = tempfile.mkstemp(prefix=".gaslight-write-check-", dir=base)
    except OSError as exc:
        raise InputError(f"cannot write in {base}: {exc.strerror or exc}", path) from None
    os.close(handle)
    os.unlink(probe)
    return path
