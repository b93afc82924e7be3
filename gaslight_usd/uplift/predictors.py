"""The exposure-predictor interface and the registry of predictors.

A predictor renders the same photo 2 EV darker (and, optionally, 2 EV
brighter) in the encoded domain. The recursion (:mod:`.recursive`) applies it
to its own output. ``ev`` tells the predictor the EV offset of the image it is
given relative to the original photo (0 for the photo, -2 after one step...):
learned predictors ignore it, the oracle needs it.

Built-in predictor modules (:data:`BUILTIN_MODULES`) each declare a table
``PREDICTORS = {name: (factory, description)}`` that this module reads on first
use; they never import this module, so the registry depends on them and not
both ways. Code may add one with :func:`register_predictor`; third parties may
also use the entry-point group ``gaslight_usd.predictors`` (a factory callable).
"""

from __future__ import annotations

import importlib
import logging
from collections.abc import Callable
from importlib.metadata import entry_points
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ..errors import InputError
from .curves import Curve

log = logging.getLogger(__name__)
ENTRY_POINT_GROUP = "gaslight_usd.predictors"
BUILTIN_MODULES = ("fast_predictor", "diffusion", "oracle")
"""Modules of this package that declare a ``PREDICTORS`` table."""


@runtime_checkable
class Predictor(Protocol):
    name: str

    def darker(self, encoded: np.ndarray, curve: Curve, ev: float) -> np.ndarray:
        """The encoded image 2 EV darker than ``encoded`` (H, W, 3) in [0, 1]."""
        ...

    def brighter(self, encoded: np.ndarray, curve: Curve, ev: float) -> np.ndarray:
        """The encoded image 2 EV brighter than ``encoded``."""
        ...


class ReexposePredictor:
    """No prediction: the photo re-exposed through its curve (clipped stays flat).

    The baseline every predictor must beat, and the default ``brighter`` of
    the others (brightening adds no highlight information).
    """

    name = "reexpose"

    def darker(self, encoded: np.ndarray, curve: Curve, ev: float) -> np.ndarray:
        return curve.reexpose(encoded, -2.0)

    def brighter(self, encoded: np.ndarray, curve: Curve, ev: float) -> np.ndarray:
        return curve.reexpose(encoded, 2.0)


Factory = Callable[..., Predictor]
_FACTORIES: dict[str, Factory] = {}
_DESCRIPTIONS: dict[str, str] = {}


def register_predictor(name: str, factory: Factory, description: str = "") -> None:
    """Make ``factory(**options)`` available as ``--predictor NAME``."""
    _FACTORIES[name] = factory
    _DESCRIPTIONS[name] = description


def _load_builtins() -> None:
    for module_name in BUILTIN_MODULES:
        module = importlib.import_module(f".{module_name}", __package__)
        for name, (factory, description) in module.PREDICTORS.items():
            if name not in _FACTORIES:
                register_predictor(name, factory, description)
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        if ep.name in _FACTORIES:
            continue
        try:
            register_predictor(ep.name, ep.load(), "plug-in")
        except Exception as exc:  # a broken plug-in must not break the tool
            log.warning("predictor plug-in %s failed to load: %s", ep.name, exc)


def available_predictors() -> dict[str, str]:
    """Name -> one-line description of every registered predictor."""
    _load_builtins()
    return dict(sorted(_DESCRIPTIONS.items()))


def get_predictor(name: str, **options: Any) -> Predictor:
    """A predictor instance by name; unknown names raise InputError listing the known."""
    _load_builtins()
    if name not in _FACTORIES:
        raise InputError(f"unknown predictor {name!r}; available: "
                         + ", ".join(sorted(_FACTORIES)))
    return _FACTORIES[name](**options)


register_predictor("reexpose", ReexposePredictor,
                   "no prediction: re-expose the photo (clipped regions stay flat)")
