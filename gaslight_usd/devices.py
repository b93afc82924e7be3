"""Which torch device the fit and the renderer run on, checked before any work."""

from __future__ import annotations

import torch

from .errors import UsageError


def resolve_device(device: str | torch.device | None) -> torch.device:
    """``cpu``, ``cuda`` or ``cuda:N`` as a torch device, or a one-line error.

    The CPU path renders with the compiled kernels; ``cuda`` runs the same
    vectorised torch renderer on the GPU (no compiled GPU kernels of our own).
    Asking for a GPU that torch cannot see fails here, not halfway through a run.
    """
    name = str(device or "cpu").strip().lower()
    try:
        dev = torch.device(name)
    except RuntimeError as err:
        raise UsageError(f"device {name!r}: expected cpu, cuda or cuda:N") from err
    if dev.type == "cpu":
        return dev
    if dev.type != "cuda":
        raise UsageError(f"device {name!r}: expected cpu, cuda or cuda:N")
    if not torch.cuda.is_available():
        raise UsageError(f"device {name!r}: this torch ({torch.__version__}) sees no CUDA GPU; "
                         "use --device cpu")
    if dev.index is not None and dev.index >= torch.cuda.device_count():
        raise UsageError(f"device {name!r}: only {torch.cuda.device_count()} CUDA GPU(s) here")
    return dev
