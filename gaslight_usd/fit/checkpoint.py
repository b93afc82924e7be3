"""Checkpoints: everything needed to resume a fit, written atomically."""

from __future__ import annotations

from pathlib import Path

import torch

from ..atomic import atomic_path


def save_checkpoint(path: Path, state: dict) -> None:
    with atomic_path(path) as tmp:
        torch.save(state, tmp)


def load_checkpoint(path: Path) -> dict | None:
    if not Path(path).exists():
        return None
    return torch.load(path, map_location="cpu", weights_only=False)
