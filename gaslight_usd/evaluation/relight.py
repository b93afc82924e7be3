"""The relighting protocol: judge an HDR image by the light it casts.

Following GaSLight (Lyu et al., ICCV 2025) and the single-image HDR
relighting evaluations it follows: the HDR image lights a white diffuse
sphere and a mirror-like sphere resting on a plane; renders of the
prediction and of the truth are compared after exposure alignment.
Rendered with Mitsuba 3 (an independent renderer), path tracer, fixed seed.

The scene (Mitsuba world, +Y up, units arbitrary):

- a diffuse plane ``y = 0``, 8 x 8, reflectance 0.5;
- a white diffuse sphere (reflectance 0.8), radius 1, centre (-1.1, 1, 0);
- a mirror sphere (perfect conductor), radius 1, centre (1.1, 1, 0);
- a camera at (0, 1.7, 7) looking at (0, 0.8, 0), vertical FOV 32 degrees,
  square image; the environment itself is hidden from the camera
  (background black) so only the light it casts is compared.

How an image becomes the environment (a lat-long map, OpenEXR convention,
``2N x N``, default 512 x 256):

- a **panorama** (a 2:1 lat-long image) is used whole, area-resampled;
- a **perspective image** is projected onto a 90-degree partial
  hemisphere: the patch spanning azimuth -45..+45 degrees around +Z (the
  direction from the spheres towards the camera, i.e. behind the camera, so
  the lit sides face the camera and the mirror sphere shows the image) and
  elevation 0..90 degrees (horizon to zenith). The image is stretched onto
  that patch linearly in angle: its columns map to azimuth (image left =
  the viewer's left when looking from the spheres towards +Z), its rows to
  elevation (top row at the zenith, bottom row on the horizon),
  independent of the photo's own field of view and aspect. The patch is the
  area-average resample of the image (a light's total power is kept), and
  everything outside it is black (zero radiance).

Comparison (:func:`compare_renders`): both renders are divided by the truth
render's 99th-percentile luminance (so the truth render spans about [0, 1]);
the prediction render is exposure-aligned by the mean of the pixels whose
truth luminance is in [0.2, 0.8]
(:func:`~gaslight_usd.evaluation.metrics.exposure_alignment_scale`); then

- ``mse`` = mean squared error of both renders clipped to [0, 1],
- ``psnr`` = ``10 log10(1 / mse)`` dB (capped at 100 dB for identical renders),
- ``angular_error_deg`` = mean angle between the unclipped RGB vectors of
  the pixels lit in both renders.

Because the path tracer is linear in the light and runs with a fixed seed
(importance sampling depends only on the normalised environment), a
prediction that is the truth times any constant renders as the truth times
that constant, and scores MSE 0 after alignment.
"""

from __future__ import annotations

import glob
import os
import time
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..cameras import is_latlong
from ..errors import GaslightError
from .metrics import (
    angular_error_deg,
    exposure_alignment_scale,
    luminance,
    mse,
    psnr_from_mse,
)
from .resample import area_resize

PREFERRED_VARIANT = "llvm_ad_rgb"
FALLBACK_VARIANT = "scalar_rgb"
USABLE_VARIANTS = ("llvm_ad_rgb", "cuda_ad_rgb", "scalar_rgb")
LIBLLVM_CANDIDATES = (
    "/usr/lib/x86_64-linux-gnu/libLLVM-19.so",
    "/usr/lib/*-linux-gnu/libLLVM-19.so*",
    "/usr/lib/llvm-19/lib/libLLVM*.so*",
)
RENDER_WHITE_PERCENTILE = 99.0
PATCH_AZIMUTH_DEG = 90.0
"""Angular width of the partial hemisphere a perspective image is projected onto."""


def _find_libllvm() -> str | None:
    for pattern in LIBLLVM_CANDIDATES:
        hits = sorted(glob.glob(pattern))
        if hits:
            return hits[0]
    return None


def llvm_variant_usable() -> bool:
    """Whether ``llvm_ad_rgb`` may be used: a vetted libLLVM (19) was found or named."""
    return bool(os.environ.get("DRJIT_LIBLLVM_PATH") or _find_libllvm())


def load_mitsuba() -> Any:
    """Import Mitsuba with a usable RGB variant and return the module.

    Prefers ``llvm_ad_rgb`` (needs a recent libLLVM: Debian's libllvm19;
    ``DRJIT_LIBLLVM_PATH`` is pointed at it when unset and found), falls back
    to the slow ``scalar_rgb`` with a warning, also when only an older
    libLLVM is installed (Dr.Jit would load it and abort). A variant already
    chosen by the caller is kept when it is an RGB one.
    """
    if "DRJIT_LIBLLVM_PATH" not in os.environ:
        found = _find_libllvm()
        if found:
            os.environ["DRJIT_LIBLLVM_PATH"] = found
    try:
        import drjit as dr
        import mitsuba as mi
    except ImportError as exc:
        raise GaslightError("the relighting metric needs Mitsuba 3: "
                            "pip install 'gaslight-usd[eval]'") from exc
    if mi.variant() in USABLE_VARIANTS:
        return mi
    try:
        if not os.environ.get("DRJIT_LIBLLVM_PATH"):
            # Left to itself Dr.Jit loads whatever libLLVM it finds; an older
            # one (Debian 12's LLVM 14/15) aborts the process ("LLVM ERROR:
            # Cannot select") on the first kernel, which no except can catch.
            raise RuntimeError("no libLLVM 19 found")
        if not dr.has_backend(dr.JitBackend.LLVM):
            raise RuntimeError("Dr.Jit found no usable LLVM library")
        mi.set_variant(PREFERRED_VARIANT)
    except Exception as exc:  # noqa: BLE001 - any failure means: use the fallback
        warnings.warn(f"Mitsuba {PREFERRED_VARIANT} unavailable ({exc}); using "
                      f"{FALLBACK_VARIANT}, which is much slower (install libllvm19 and set "
                      "DRJIT_LIBLLVM_PATH)", RuntimeWarning, stacklevel=2)
        mi.set_variant(FALLBACK_VARIANT)
    return mi


def environment_from_perspective(image: np.ndarray, env_height: int = 256) -> np.ndarray:
    """Project a perspective image onto the 90-degree partial hemisphere (see module doc).

    Returns a ``(env_height, 2 * env_height, 3)`` lat-long map, zero outside the patch.
    """
    h, w = env_height, 2 * env_height
    patch_w = int(round(w * PATCH_AZIMUTH_DEG / 360.0))
    env = np.zeros((h, w, 3), np.float32)
    left = (w - patch_w) // 2  # the centre column looks along +Z
    patch = area_resize(np.maximum(image[..., :3], 0), h // 2, patch_w)
    env[: h // 2, left:left + patch_w] = patch
    return env


def environment_from_panorama(panorama: np.ndarray, env_height: int = 256) -> np.ndarray:
    """A lat-long panorama area-resampled to ``(env_height, 2 * env_height, 3)``."""
    return area_resize(np.maximum(panorama[..., :3], 0), env_height, 2 * env_height)


def environment_for(image: np.ndarray, env_height: int = 256, kind: str = "auto") -> np.ndarray:
    """The environment map an image makes: ``kind`` is auto, panorama or perspective."""
    if kind not in ("auto", "panorama", "perspective"):
        raise ValueError(f"kind must be auto, panorama or perspective, not {kind!r}")
    pano = is_latlong(image.shape[1], image.shape[0]) if kind == "auto" else kind == "panorama"
    if pano:
        return environment_from_panorama(image, env_height)
    return environment_from_perspective(image, env_height)


def _scene_dict(mi: Any, env: np.ndarray, resolution: int, spp: int,
                max_depth: int) -> dict:
    T = mi.ScalarTransform4f
    diffuse = {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.8}}
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": max_depth, "hide_emitters": True},
        "sensor": {
            "type": "perspective", "fov": 32.0, "fov_axis": "y",
            "to_world": T().look_at(origin=[0, 1.7, 7.0], target=[0, 0.8, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": resolution, "height": resolution,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "plane": {"type": "rectangle", "to_world": T().rotate([1, 0, 0], -90).scale(4.0),
                  "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.5}}},
        "diffuse_sphere": {"type": "sphere", "center": [-1.1, 1.0, 0.0], "radius": 1.0,
                           "bsdf": diffuse},
        "mirror_sphere": {"type": "sphere", "center": [1.1, 1.0, 0.0], "radius": 1.0,
                          "bsdf": {"type": "conductor", "material": "none"}},
        "environment": {"type": "envmap", "bitmap": mi.Bitmap(env)},
    }


@dataclass
class RelightRenderer:
    """The relighting scene, built once; each render swaps the environment texture.

    ``resolution`` (square image side) and ``spp`` trade noise for time: the
    protocol default is 256 x 256 at 64 spp; the bench uses less and says so.
    ``seconds`` lists the wall time of every render (the first includes
    Mitsuba's JIT compilation).
    """

    resolution: int = 256
    spp: int = 64
    env_height: int = 256
    seed: int = 0
    max_depth: int = 4
    seconds: list[float] = field(default_factory=list)
    _scene: Any = field(default=None, repr=False)
    _params: Any = field(default=None, repr=False)
    _mi: Any = field(default=None, repr=False)

    @property
    def variant(self) -> str:
        return str(self._mi.variant()) if self._mi else "not loaded"

    def _ensure_scene(self, env: np.ndarray) -> None:
        if self._scene is None:
            self._mi = self._mi or load_mitsuba()
            self._scene = self._mi.load_dict(
                _scene_dict(self._mi, env, self.resolution, self.spp, self.max_depth))
            self._params = self._mi.traverse(self._scene)

    def _first_render(self, env: np.ndarray) -> np.ndarray:
        """Build the scene and render; an LLVM too old for Mitsuba falls back to scalar."""
        self._ensure_scene(env)
        try:
            return np.array(self._mi.render(self._scene, seed=self.seed), np.float32)[..., :3]
        except Exception as exc:  # noqa: BLE001 - e.g. "Cannot select ... fminimum"
            if self._mi.variant() == FALLBACK_VARIANT:
                raise
            warnings.warn(f"Mitsuba {self._mi.variant()} failed to render ({exc}); retrying "
                          f"with {FALLBACK_VARIANT}", RuntimeWarning, stacklevel=3)
            self._mi.set_variant(FALLBACK_VARIANT)
            self._scene = None
            self._ensure_scene(env)
            return np.array(self._mi.render(self._scene, seed=self.seed), np.float32)[..., :3]

    def render_environment(self, env: np.ndarray) -> np.ndarray:
        """Render the scene lit by a lat-long map ``(env_height, 2 env_height, 3)``."""
        env = np.ascontiguousarray(env, np.float32)
        if env.shape != (self.env_height, 2 * self.env_height, 3):
            raise ValueError(f"environment must be {(self.env_height, 2 * self.env_height, 3)}, "
                             f"got {env.shape}")
        start = time.perf_counter()
        if self._scene is None:
            image = self._first_render(env)
            self.seconds.append(time.perf_counter() - start)
            return image
        # Mitsuba's envmap stores one wrapped column on each side.
        padded = np.concatenate([env[:, -1:], env, env[:, :1]], axis=1)
        self._params["environment.data"] = self._mi.TensorXf(padded)
        self._params.update()
        image = np.array(self._mi.render(self._scene, seed=self.seed), dtype=np.float32)
        self.seconds.append(time.perf_counter() - start)
        return image[..., :3]

    def render(self, image: np.ndarray, kind: str = "auto") -> np.ndarray:
        """Render the scene lit by an HDR image (panorama or perspective, see module doc)."""
        return self.render_environment(environment_for(image, self.env_height, kind))


@dataclass(frozen=True)
class RelightScores:
    mse: float
    psnr: float
    angular_error_deg: float
    exposure_scale: float
    """Factor applied to the prediction's render to align its exposure."""


def compare_renders(pred_render: np.ndarray, truth_render: np.ndarray) -> RelightScores:
    """MSE, PSNR and angular error of two renders, exposure-aligned (see module doc)."""
    yt = luminance(truth_render)
    white = float(np.percentile(yt, RENDER_WHITE_PERCENTILE))
    if white <= 0:
        white = float(yt.max()) or 1.0
    t = np.asarray(truth_render, np.float64) / white
    p = np.asarray(pred_render, np.float64) / white
    scale = exposure_alignment_scale(p, t)
    p = p * scale
    error = mse(np.clip(p, 0, 1), np.clip(t, 0, 1))
    return RelightScores(mse=error, psnr=psnr_from_mse(error, 1.0),
                         angular_error_deg=angular_error_deg(p, t), exposure_scale=scale)


def relight_scores(pred: np.ndarray, truth: np.ndarray, renderer: RelightRenderer | None = None,
                   kind: str = "auto", truth_render: np.ndarray | None = None) -> RelightScores:
    """Render ``pred`` and ``truth`` (or reuse ``truth_render``) and compare the renders."""
    renderer = renderer or RelightRenderer()
    if truth_render is None:
        truth_render = renderer.render(truth, kind)
    return compare_renders(renderer.render(pred, kind), truth_render)
