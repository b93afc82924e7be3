"""Camera curves: encoded (display) values <-> linear values, channel by channel.

Prediction and merging happen in the encoded domain the paper uses; a
:class:`Curve` linearises each exposure of a stack. The paper linearises with
``v ** 2.2``; for real photos we use the photo's true input transform when the
OCIO input space splits into a per-channel curve followed by a 3x3 matrix (true
of sRGB, gamma and log encodings): :func:`input_transform` recovers both from
OCIO and checks the split, so that unclipped pixels come out exactly as the
plain linearisation would, and the result is converted to the working space
once, by the matrix.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .. import colour
from ..errors import InputError

Array = np.ndarray


@dataclass(frozen=True)
class Curve:
    """A monotone per-channel transfer: ``to_linear`` and its inverse ``to_encoded``.

    ``to_linear(1.0) == 1.0``: linear values are relative to the encoding's white.
    Values above 1 in linear encode to 1 (the sensor clips).
    """

    name: str
    to_linear: Callable[[Array], Array]
    to_encoded: Callable[[Array], Array]

    def reexpose(self, encoded: Array, stops: float) -> Array:
        """The encoded image ``stops`` EV brighter (negative: darker), clipped at 1."""
        lin = self.to_linear(np.clip(encoded, 0.0, 1.0)) * np.float32(2.0 ** stops)
        return np.clip(self.to_encoded(np.clip(lin, 0.0, 1.0)), 0.0, 1.0).astype(np.float32)


def _gamma(g: float) -> Curve:
    return Curve(f"gamma{g:g}",
                 lambda v: np.power(np.clip(v, 0.0, None), g).astype(np.float32),
                 lambda x: np.power(np.clip(x, 0.0, None), 1.0 / g).astype(np.float32))


def _srgb_to_linear(v: Array) -> Array:
    return colour.srgb_decode(np.clip(v, 0.0, None)).astype(np.float32)


def _srgb_to_encoded(x: Array) -> Array:
    return colour.srgb_encode(np.clip(x, 0.0, None)).astype(np.float32)


GAMMA22 = _gamma(2.2)
SRGB = Curve("srgb", _srgb_to_linear, _srgb_to_encoded)


TABLE_SIZE = 65536


def _uniform_lookup(table: np.ndarray, position: Array) -> Array:
    """Nearest entry of ``table`` sampled uniformly on [0, 1] (one gather: fast).

    With 65536 entries the step is 1.5e-5 of full scale, far below 8- or
    16-bit quantisation.
    """
    n = len(table) - 1
    index = np.clip(np.asarray(position, np.float32), 0.0, 1.0) * np.float32(n) + 0.5
    return table[index.astype(np.int32)]


def lut_curve(name: str, encoded_levels: Array, linear_levels: Array) -> Curve:
    """A curve from a monotone table, looked up on uniform grids both ways (fast).

    The forward table is resampled to uniform encoded levels; the inverse is
    tabulated on a uniform grid of ``sqrt(linear)`` (dense near black, where
    display curves are steep).
    """
    enc = np.asarray(encoded_levels, np.float64)
    lin = np.maximum.accumulate(np.asarray(linear_levels, np.float64))
    lin = lin / lin[-1]
    grid = np.linspace(0.0, 1.0, TABLE_SIZE)
    forward = np.interp(grid, enc, lin).astype(np.float32)
    inverse = np.interp(grid * grid, lin, enc).astype(np.float32)

    def to_linear(v: Array) -> Array:
        return _uniform_lookup(forward, v)

    def to_encoded(x: Array) -> Array:
        return _uniform_lookup(inverse, np.sqrt(np.clip(x, 0.0, 1.0)))

    return Curve(name, to_linear, to_encoded)


CURVES = {"srgb": SRGB, "gamma2.2": GAMMA22, "gamma22": GAMMA22, "linear": _gamma(1.0)}


def curve_by_name(name: str) -> Curve:
    try:
        return CURVES[name.lower()]
    except KeyError:
        raise InputError(f"unknown camera curve {name!r}; known: "
                         + ", ".join(sorted(CURVES))) from None


@dataclass(frozen=True)
class InputTransform:
    """encoded photo -> working space as ``matrix @ curve.to_linear(encoded)``."""

    curve: Curve
    matrix: Array
    """(3, 3): working = linear @ matrix.T"""
    exact: bool
    """False when the OCIO transform did not split; the curve is then gamma 2.2."""

    def to_working(self, linear: Array) -> Array:
        return np.einsum("...c,dc->...d", linear, self.matrix).astype(np.float32)


@lru_cache(maxsize=16)
def input_transform(input_space: str, working_space: str,
                    config_uri: str | None = None, tolerance: float = 2e-3) -> InputTransform:
    """Split the OCIO input transform into a per-channel curve and a matrix.

    The curve is sampled on neutral greys (4097 levels), the matrix on the
    primaries, and the split is checked on random colours; when it fails
    (a transform with cross-channel curves) the paper's gamma 2.2 is used
    with the primaries matrix and ``exact=False``.
    """
    levels = np.linspace(0.0, 1.0, 4097, dtype=np.float32)
    greys = np.repeat(levels[:, None], 3, axis=1)
    white = colour.convert(np.ones((1, 3), np.float32), input_space, working_space, config_uri)[0]
    matrix = colour.convert(np.eye(3, dtype=np.float32), input_space, working_space,
                            config_uri).T.astype(np.float64)
    try:
        curve_lin = np.linalg.solve(matrix, colour.convert(greys, input_space, working_space,
                                                           config_uri).T.astype(np.float64))
    except np.linalg.LinAlgError:
        return InputTransform(GAMMA22, matrix.astype(np.float32), False)
    curve_lin = curve_lin.mean(axis=0)
    exact = bool(np.all(np.isfinite(curve_lin)) and abs(curve_lin[-1] - 1.0) < 1e-3
                 and np.all(np.diff(curve_lin) >= -1e-6) and np.all(white > 0))
    curve = lut_curve(f"ocio:{input_space}", levels, curve_lin) if exact else GAMMA22
    if exact:
        rng = np.random.default_rng(0)
        probe = rng.random((256, 3), dtype=np.float32)
        truth = colour.convert(probe, input_space, working_space, config_uri)
        split = np.einsum("nc,dc->nd", curve.to_linear(probe), matrix)
        exact = bool(np.max(np.abs(split - truth)) <= tolerance * max(1.0, float(truth.max())))
        if not exact:
            curve = GAMMA22
    return InputTransform(curve, matrix.astype(np.float32), exact)
