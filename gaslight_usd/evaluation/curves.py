"""Camera curves: linear sensor values in [0, 1] <-> encoded values in [0, 1].

- ``srgb``: the IEC 61966-2-1 sRGB transfer function (piecewise: linear toe
  ``12.92 x`` below 0.0031308, else ``1.055 x^(1/2.4) - 0.055``).
- ``gamma2.2``: a pure power law ``x^(1/2.2)``.
- ``filmic``: John Hable's filmic curve (the "Uncharted 2" operator, GDC
  2010: ``f(x) = (x(Ax + CB) + DE) / (x(Ax + B) + DF) - E/F`` with A 0.15,
  B 0.50, C 0.10, D 0.20, E 0.02, F 0.30) applied to ``11.2 x`` and
  normalised by ``f(11.2)`` so sensor white stays 1, then display-encoded
  with ``^(1/2.2)``. It compresses highlights the way a camera's picture
  profile does, so a naive inverse gamma no longer linearises it. Its
  inverse is a monotone table lookup (accurate to about 1e-6).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache

import numpy as np

from ..colour import srgb_decode, srgb_encode

CURVE_NAMES = ("srgb", "gamma2.2", "filmic")
_HABLE = (0.15, 0.50, 0.10, 0.20, 0.02, 0.30)
_HABLE_WHITE = 11.2


def _hable(x: np.ndarray) -> np.ndarray:
    a, b, c, d, e, f = _HABLE
    return (x * (a * x + c * b) + d * e) / (x * (a * x + b) + d * f) - e / f


def _filmic_encode(x: np.ndarray) -> np.ndarray:
    tone = _hable(_HABLE_WHITE * x) / _hable(np.float64(_HABLE_WHITE))
    return np.power(np.maximum(tone, 0.0), 1 / 2.2)


@lru_cache(maxsize=1)
def _filmic_table() -> tuple[np.ndarray, np.ndarray]:
    # Dense in the toe, where the curve is steep: sample x on a squared grid.
    x = np.linspace(0.0, 1.0, 65537) ** 2
    return _filmic_encode(x), x


def _filmic_decode(v: np.ndarray) -> np.ndarray:
    encoded, linear = _filmic_table()
    return np.interp(v, encoded, linear)


_Fn = Callable[[np.ndarray], np.ndarray]
_CURVES: dict[str, tuple[_Fn, _Fn]] = {
    "srgb": (srgb_encode, srgb_decode),
    "gamma2.2": (lambda x: np.power(x, 1 / 2.2), lambda v: np.power(v, 2.2)),
    "filmic": (_filmic_encode, _filmic_decode),
}


def _get(name: str) -> tuple[Callable, Callable]:
    try:
        return _CURVES[name]
    except KeyError:
        raise ValueError(f"unknown camera curve {name!r}; "
                         f"one of {', '.join(CURVE_NAMES)}") from None


def encode(linear: np.ndarray, curve: str) -> np.ndarray:
    """Linear sensor values (clipped to [0, 1]) -> encoded values in [0, 1], float32."""
    x = np.clip(np.asarray(linear, np.float64), 0.0, 1.0)
    return _get(curve)[0](x).astype(np.float32)


def decode(encoded: np.ndarray, curve: str) -> np.ndarray:
    """Encoded values in [0, 1] -> linear sensor values in [0, 1] (the inverse curve), float32."""
    v = np.clip(np.asarray(encoded, np.float64), 0.0, 1.0)
    return _get(curve)[1](v).astype(np.float32)
