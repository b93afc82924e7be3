"""Photo set -> HDR views: what the uplift converters share.

Each photo is uplifted in its encoded domain (prediction and merge), linearised
through the photo's own input transform (see :mod:`.curves`), converted to the
working space once, and divided by its exposure ratio so every view is on the
set's relative-radiance scale (as :mod:`gaslight_usd.poses.views` defines it).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import OpenImageIO as oiio

from ..atomic import atomic_path
from ..cameras import is_latlong
from ..colour import CLIP_LEVEL
from ..errors import InputError
from ..poses.views import View
from .curves import InputTransform, input_transform
from .panorama import uplift_panorama
from .predictors import Predictor, get_predictor
from .recursive import MAX_STEPS, THRESHOLD, uplift_recursive

log = logging.getLogger(__name__)


@dataclass
class UpliftOptions:
    """The options of the recursive uplift (converter ``uplift.recursive``); the CLI
    reads its defaults from here."""

    predictor: str = "fast"
    weights: str | None = None
    threshold: float = THRESHOLD
    max_steps: int = MAX_STEPS
    brighter: bool = False
    save_stacks: bool = False
    panorama: str = "auto"
    """auto (2:1 images are panoramas), on, off"""
    max_size: int = 0
    """Long side (pixels) photos are shrunk to before the uplift (0: as shot). ``run``
    sets it from the fit's working size, so nothing works on pixels the fit drops."""
    extra: dict[str, Any] = field(default_factory=dict)
    """Further keyword options of the predictor (a plug-in's own)."""


def check_photo(view: View) -> None:
    """Refuse photos the uplift cannot mean anything for; warn on degenerate ones."""
    if view.encoded.size == 0:
        raise InputError("empty image", view.path)
    if float(view.encoded.max()) > 1.0 + 1e-3:
        raise InputError("holds values above 1: this is an HDR image already, not a photo",
                         view.path)


def make_predictor(opts: UpliftOptions) -> Predictor:
    kwargs: dict[str, Any] = dict(opts.extra)
    if opts.weights:
        kwargs["weights"] = opts.weights
    return get_predictor(opts.predictor, **kwargs)


def write_stack(folder: Path, name: str, stack: list[np.ndarray], evs: list[float]) -> None:
    """The predicted exposures as 16-bit PNGs ``<name>_ev<+/-k>.png`` (encoded values)."""
    folder.mkdir(parents=True, exist_ok=True)
    for img, ev in zip(stack, evs, strict=True):
        final = folder / f"{name}_ev{ev:+g}.png"
        with atomic_path(final) as tmp:
            data = np.round(np.clip(img, 0, 1) * 65535).astype(np.uint16)
            out = oiio.ImageOutput.create(str(tmp))
            spec = oiio.ImageSpec(data.shape[1], data.shape[0], 3, oiio.UINT16)
            out.open(str(tmp), spec)
            out.write_image(data)
            out.close()


@dataclass
class ViewUplift:
    radiance: np.ndarray
    """Working-space relative radiance."""
    attributes: dict[str, Any]


def uplift_view(view: View, predictor: Predictor, transform: InputTransform,
                opts: UpliftOptions, stack_dir: Path | None = None) -> ViewUplift:
    """Uplift one photo by recursive prediction; see the module docstring."""
    check_photo(view)
    curve = transform.curve
    encoded = view.encoded
    h, w = encoded.shape[:2]
    panorama = opts.panorama == "on" or (opts.panorama == "auto" and is_latlong(w, h))
    steps: list[int] = []

    def one(enc: np.ndarray) -> np.ndarray:
        res = uplift_recursive(enc, predictor, curve, opts.threshold, opts.max_steps,
                               opts.brighter)
        steps.append(res.darker_steps)
        if stack_dir is not None and not panorama:
            write_stack(stack_dir, view.name, res.stack, res.evs)
        one.darkest = res.stack[int(np.argmin(res.evs))]  # type: ignore[attr-defined]
        return res.linear

    if panorama:
        linear = uplift_panorama(encoded, one)
        after = float(np.mean(curve.to_encoded(np.clip(
            linear * 2.0 ** (-2 * max(steps)), 0, 1)).max(axis=-1) >= CLIP_LEVEL))
    else:
        linear = one(encoded)
        after = float(np.mean(one.darkest.max(axis=-1) >= CLIP_LEVEL))  # type: ignore[attr-defined]
    radiance = transform.to_working(linear) / np.float32(view.exposure_ratio)
    attrs = {
        "gaslight:predictor": predictor.name,
        "gaslight:ev_steps": int(max(steps)),
        "gaslight:min_ev": float(-2 * max(steps)),
        "gaslight:threshold": float(opts.threshold),
        "gaslight:curve": curve.name,
        "gaslight:curve_exact": int(transform.exact),
        "gaslight:panorama": int(panorama),
        "gaslight:clipped_fraction_after": after,
    }
    return ViewUplift(np.maximum(radiance, 0.0).astype(np.float32), attrs)


def transform_for(input_space: str, working_space: str, config_uri: str | None
                  ) -> InputTransform:
    transform = input_transform(input_space, working_space, config_uri)
    if not transform.exact:
        log.warning("input space %r does not split into a curve and a matrix; "
                    "linearising the stack with gamma 2.2 (the paper's choice)", input_space)
    return transform
