"""A display-referred copy of an HDR splat PLY, for viewers that clip HDR.

Splat viewers treat 3DGS colours as display values in [0, 1]. The copy:

1. converts the linear base (DC) colour from the working space to linear
   Rec.709 (OCIO);
2. multiplies by ``2 ** exposure_ev`` (default: the value that puts the
   opacity-weighted median luminance at 0.18, middle grey);
3. tone-maps each channel with Reinhard ``x / (1 + x)`` (monotonic, never clips);
4. encodes with the sRGB transfer function (OCIO "sRGB Encoded Rec.709 (sRGB)").

Higher SH bands are scaled per channel by the same display/linear ratio, so
view dependence keeps its relative strength. The exposure, tone map and
colour space are written as PLY header comments (``comment gaslight ...``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from . import colour
from .ply import write_ply
from .splats import SplatScene, rgb_to_sh_dc, sh_dc_to_rgb

DISPLAY_SPACE = "sRGB Encoded Rec.709 (sRGB)"
MIDDLE_GREY = 0.18


def auto_exposure(linear_rec709: np.ndarray, opacities: np.ndarray) -> float:
    """EV that puts the opacity-weighted median luminance at middle grey."""
    lum = linear_rec709 @ np.array(colour.REC709_Y)
    if lum.size == 0 or not np.any(lum > 0):
        return 0.0
    order = np.argsort(lum)
    cdf = np.cumsum(opacities[order])
    median = float(lum[order][np.searchsorted(cdf, cdf[-1] / 2)])
    return float(np.log2(MIDDLE_GREY / max(median, 1e-6)))


def display_scene(scene: SplatScene, exposure_ev: float | None = None,
                  working_space: str | None = None, config_uri: str | None = None
                  ) -> SplatScene:
    """The display-referred copy of ``scene`` (metadata says how it was made)."""
    space = working_space or str(scene.metadata.get("colour_space")
                                 or colour.DEFAULT_WORKING_SPACE)
    base = sh_dc_to_rgb(scene.sh[:, 0]).astype(np.float64)
    linear = colour.convert(np.maximum(base, 0.0), space, colour.DEFAULT_LINEAR_FILE_SPACE,
                            config_uri).astype(np.float64)
    ev = auto_exposure(linear, scene.opacities) if exposure_ev is None else float(exposure_ev)
    exposed = np.maximum(linear * 2.0**ev, 0.0)
    toned = exposed / (1.0 + exposed)
    display = colour.convert(toned.astype(np.float32), colour.DEFAULT_LINEAR_FILE_SPACE,
                             DISPLAY_SPACE, config_uri).astype(np.float64)
    ratio = np.where(np.abs(base) > 1e-6, display / np.where(np.abs(base) > 1e-6, base, 1.0),
                     0.0)
    sh = scene.sh.copy()
    sh[:, 0] = rgb_to_sh_dc(display)
    sh[:, 1:] *= ratio[:, None, :].astype(np.float32)
    meta = dict(scene.metadata)
    meta.update(colour_space=DISPLAY_SPACE, display_referred=True,
                display_exposure_ev=round(ev, 4),
                display_tone_map="Reinhard x/(1+x) per channel after exposure, linear Rec.709",
                display_source_space=space)
    return SplatScene(scene.positions, scene.rotations, scene.log_scales,
                      scene.opacity_logits, sh.astype(np.float32), scene.normals, meta)


def write_display_ply(path: str | Path, scene: SplatScene, exposure_ev: float | None = None,
                      working_space: str | None = None, config_uri: str | None = None
                      ) -> float:
    """Write the display-referred copy; return the exposure (EV) it used."""
    shown = display_scene(scene, exposure_ev, working_space, config_uri)
    write_ply(path, shown)
    return float(shown.metadata["display_exposure_ev"])
