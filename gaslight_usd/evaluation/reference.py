"""LDR/HDR test pairs from real HDR images: the ground truth of the uplift bench.

A pair is what a camera would have made of a real scene, and the scene's true
radiance: a crop of a real HDR image (a perspective view of a lat-long
panorama at a chosen field of view and direction, or a window of an ordinary
HDR image), exposed, clipped at the sensor's white, encoded through a camera
curve (:mod:`~gaslight_usd.evaluation.curves`) and quantised to 8 bits.

Scale: ``pair.truth`` is relative radiance with 1.0 at the sensor white of
the LDR photo, so ``decode(pair.ldr, pair.curve)`` (the no-uplift baseline)
equals ``pair.truth`` wherever nothing clipped (up to quantisation).

Exposure: the camera meters the crop: its median luminance lands at
``0.18 * 2^ev_offset`` with ``ev_offset`` drawn in ``ev_range``.

Determinism: pair ``i`` depends only on ``(seed, i)`` and the sources, so a
bigger ``count`` extends a smaller run's pairs.

Light-source truth: some real HDR files clamp their brightest pixels (the
shared set: city, interior and sunrise at about 32000 in the sun's core,
studio at 100; forest, sunset, courtyard and night are unclipped). A source
may carry a ``clamp_level``; a crop that holds any source pixel above half
that level has ``light_truth = False`` and must not be used to judge
light-source accuracy. For files given by the user, a peak at the top of the
half-float range (>= 65000) marks the source as clamped.

Nothing derived is committed: pairs are built in memory by tests and benches
(:func:`write_pairs` writes them out for inspection or other tools).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..atomic import write_text
from ..cameras import PinholeCamera, is_latlong, sample_latlong
from ..errors import InputError
from ..imageio import read_image, write_exr
from ..locate import shared_hdri_dir
from . import curves
from .metrics import luminance
from .resample import area_resize

SHARED_CLAMP_LEVELS: dict[str, float] = {
    "city": 32000.0, "interior": 32000.0, "sunrise": 32000.0, "studio": 100.0,
}
"""Known clamp levels of the shared CC0 panoramas (see ../shared/data/README.md)."""
HALF_CLAMP = 65000.0
MIDDLE_GREY = 0.18


def default_hdri_dir() -> Path:
    """``$GASLIGHT_HDRI_DIR``, else ``shared/data/hdri`` found from the working
    directory upwards or beside the checkout (see :mod:`gaslight_usd.locate`)."""
    return shared_hdri_dir()


@dataclass
class HDRSource:
    """A real HDR image to cut pairs from."""

    name: str
    pixels: np.ndarray
    """(H, W, 3) float32 linear radiance, negatives clamped to 0."""
    colour_space: str
    panorama: bool
    clamp_level: float | None = None
    path: Path | None = None

    @property
    def light_truth(self) -> bool:
        """True when no pixel of the source was clamped."""
        return self.clamp_level is None

    def clamp_mask(self) -> np.ndarray:
        """(H, W) float mask of pixels whose truth is unreliable (above half the clamp)."""
        if self.clamp_level is None:
            return np.zeros(self.pixels.shape[:2], np.float32)
        return (self.pixels.max(axis=-1) >= 0.5 * self.clamp_level).astype(np.float32)


def load_source(path: str | Path, clamp_level: float | None = None,
                panorama: bool | None = None) -> HDRSource:
    """Read an HDR image (EXR/HDR) as a pair source.

    ``panorama`` defaults to "the image is 2:1"; ``clamp_level`` defaults to
    the known level of a shared panorama (a file of :func:`default_hdri_dir`,
    by stem: :data:`SHARED_CLAMP_LEVELS`), else, for a peak at the half-float
    ceiling, that peak, else None (trusted).
    """
    path = Path(path)
    image = read_image(path)
    pixels = np.maximum(image.pixels, 0.0).astype(np.float32)
    if float(pixels.max(initial=0.0)) <= 0:
        raise InputError("image is black: no radiance to build pairs from", path)
    if clamp_level is None:
        peak = float(pixels.max())
        if path.parent.resolve() == default_hdri_dir().resolve():
            clamp_level = SHARED_CLAMP_LEVELS.get(path.stem)
        if clamp_level is None and peak >= HALF_CLAMP:
            clamp_level = peak
    if panorama is None:
        panorama = is_latlong(pixels.shape[1], pixels.shape[0])
    return HDRSource(name=path.stem, pixels=pixels, colour_space=image.colour_space,
                     panorama=panorama, clamp_level=clamp_level, path=path)


def shared_sources(folder: str | Path | None = None) -> list[HDRSource]:
    """The eight shared CC0 panoramas (or every EXR/HDR in ``folder``), sorted by name."""
    folder = Path(folder) if folder else default_hdri_dir()
    if not folder.is_dir():
        raise InputError("no folder of HDR images here (set GASLIGHT_HDRI_DIR)", folder)
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in (".exr", ".hdr"))
    if not files:
        raise InputError("folder holds no EXR or HDR images", folder)
    return [load_source(p) for p in files]


@dataclass
class CropSpec:
    """How one pair was made (all angles in degrees; NaN where not applicable)."""

    source: str
    index: int
    curve: str
    ev_offset: float
    width: int
    height: int
    fov: float = math.nan
    yaw: float = math.nan
    pitch: float = math.nan
    aimed_at_light: bool = False
    window: tuple[int, int, int, int] | None = None
    """(top, left, height, width) of the window, for non-panorama sources."""


@dataclass
class ReferencePair:
    """An LDR photo and its true HDR radiance (see the module doc for the scale)."""

    name: str
    spec: CropSpec
    truth: np.ndarray
    """(H, W, 3) float32 relative radiance, 1.0 = the photo's white."""
    ldr: np.ndarray
    """(H, W, 3) float32 encoded values in [0, 1] (8-bit levels)."""
    curve: str
    colour_space: str
    exposure: float
    """Factor from the source's radiance to ``truth``."""
    light_truth: bool
    solid_angles: np.ndarray = field(repr=False)
    """(H, W) solid angle of every pixel in steradians (ones for windows)."""

    @property
    def clipped_fraction(self) -> float:
        return float(np.mean(np.any(self.truth >= 1.0, axis=-1)))

    @property
    def light_clipped(self) -> bool:
        """The brightest part of the scene is clipped in the photo (the uplift's job)."""
        return bool(luminance(self.truth).max() > 1.0)


def look_camera(yaw_deg: float, pitch_deg: float, fov_deg: float, width: int,
                height: int) -> PinholeCamera:
    """A pinhole at the origin looking along lat-long direction (yaw, pitch), horizontal FOV.

    Yaw is the lat-long longitude (0 looks along +Z, 90 along +X), pitch the
    latitude; the image's up is the world's +Y as far as the pitch allows.
    """
    yaw, pitch = math.radians(yaw_deg), math.radians(pitch_deg)
    forward = np.array([math.sin(yaw) * math.cos(pitch), math.sin(pitch),
                        math.cos(yaw) * math.cos(pitch)])
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    f = 0.5 * width / math.tan(math.radians(fov_deg) / 2)
    return PinholeCamera(width, height, f, f, width / 2, height / 2,
                         R=np.stack([right, down, forward]), t=np.zeros(3))


def pixel_solid_angles(camera: PinholeCamera) -> np.ndarray:
    """(H, W) solid angle of each pinhole pixel: ``cos^3(theta) / (fx fy)`` sr."""
    xs = (np.arange(camera.width) + 0.5 - camera.cx) / camera.fx
    ys = (np.arange(camera.height) + 0.5 - camera.cy) / camera.fy
    gx, gy = np.meshgrid(xs, ys)
    return (1.0 / (camera.fx * camera.fy) / (1 + gx * gx + gy * gy) ** 1.5).astype(np.float32)


def perspective_crop(panorama: np.ndarray, camera: PinholeCamera,
                     supersample: int = 2) -> np.ndarray:
    """Render a pinhole view of a lat-long panorama (bilinear, ``supersample``^2 rays/pixel)."""
    ss = max(1, int(supersample))
    big = PinholeCamera(camera.width * ss, camera.height * ss, camera.fx * ss, camera.fy * ss,
                        camera.cx * ss, camera.cy * ss, camera.R, camera.t)
    values = sample_latlong(panorama, big.ray_directions())
    return area_resize(values, camera.height, camera.width) if ss > 1 else values


def _peak_direction(source: HDRSource) -> tuple[float, float]:
    """(yaw, pitch) in degrees of the source's brightest pixel."""
    y = luminance(source.pixels)
    row, col = np.unravel_index(int(np.argmax(y)), y.shape)
    h, w = y.shape
    lon = -360.0 * ((col + 0.5) / w - 0.5)
    lat = 180.0 * (0.5 - (row + 0.5) / h)
    return lon, lat


def make_pair(source: HDRSource, index: int, seed: int = 0, width: int = 256, height: int = 192,
              fovs: tuple[float, ...] = (50.0, 60.0, 75.0, 90.0),
              curve_names: tuple[str, ...] = curves.CURVE_NAMES,
              ev_range: tuple[float, float] = (-1.0, 1.0), aim_light_fraction: float = 0.5,
              bits: int = 8) -> ReferencePair:
    """Pair ``index`` of ``source``: every random choice comes from ``(seed, index)``."""
    rng = np.random.default_rng([seed, index])
    curve = str(curve_names[int(rng.integers(len(curve_names)))])
    ev_offset = float(rng.uniform(*ev_range))
    if source.panorama:
        fov = float(fovs[int(rng.integers(len(fovs)))])
        aimed = bool(rng.uniform() < aim_light_fraction)
        if aimed:
            yaw, pitch = _peak_direction(source)
            yaw += float(rng.uniform(-fov / 3, fov / 3))
            pitch += float(rng.uniform(-fov / 4, fov / 4) * height / width)
        else:
            yaw, pitch = float(rng.uniform(-180.0, 180.0)), float(rng.uniform(-20.0, 40.0))
        pitch = float(np.clip(pitch, -70.0, 70.0))
        camera = look_camera(yaw, pitch, fov, width, height)
        if source.clamp_level is None:
            radiance, unreliable = perspective_crop(source.pixels, camera), np.zeros(1)
        else:  # the clamp mask rides along as a 4th channel
            stacked = np.concatenate([source.pixels, source.clamp_mask()[..., None]], axis=-1)
            both = perspective_crop(stacked, camera)
            radiance, unreliable = both[..., :3], both[..., 3]
        solid = pixel_solid_angles(camera)
        spec = CropSpec(source.name, index, curve, ev_offset, width, height, fov, yaw, pitch,
                        aimed)
    else:
        sh, sw = source.pixels.shape[:2]
        scale = min(sh / height, sw / width) * float(rng.uniform(0.6, 1.0))
        wh, ww = max(1, int(height * scale)), max(1, int(width * scale))
        top, left = int(rng.integers(sh - wh + 1)), int(rng.integers(sw - ww + 1))
        window = source.pixels[top:top + wh, left:left + ww]
        radiance = area_resize(window, height, width)
        unreliable = source.clamp_mask()[top:top + wh, left:left + ww]
        solid = np.ones((height, width), np.float32)
        spec = CropSpec(source.name, index, curve, ev_offset, width, height,
                        window=(top, left, wh, ww))
    y = luminance(radiance)
    metered = float(np.median(y))
    if metered <= 0:
        metered = float(np.mean(y)) or 1.0
    exposure = MIDDLE_GREY * 2.0 ** ev_offset / metered
    truth = (radiance * exposure).astype(np.float32)
    encoded = curves.encode(truth, curve)
    if bits:
        levels = float(2 ** bits - 1)
        encoded = (np.round(encoded * levels) / levels).astype(np.float32)
    return ReferencePair(
        name=f"{source.name}-{index:04d}", spec=spec, truth=truth, ldr=encoded, curve=curve,
        colour_space=source.colour_space, exposure=exposure,
        light_truth=bool(np.max(unreliable, initial=0.0) <= 0), solid_angles=solid,
    )


def build_pairs(sources: list[HDRSource] | None = None, count: int = 8, seed: int = 0,
                **options) -> list[ReferencePair]:
    """``count`` pairs cycling through ``sources`` (default: the shared panoramas).

    Pair ``i`` comes from source ``i % len(sources)``; ``options`` go to
    :func:`make_pair` (width, height, fovs, curve_names, ev_range,
    aim_light_fraction, bits).
    """
    sources = sources if sources is not None else shared_sources()
    if not sources:
        raise InputError("no HDR sources to build reference pairs from")
    return [make_pair(sources[i % len(sources)], i, seed, **options) for i in range(count)]


def write_pairs(pairs: list[ReferencePair], folder: str | Path) -> Path:
    """Write each pair as ``NAME.truth.exr`` + ``NAME.ldr.png`` and a ``pairs.json`` manifest."""
    import OpenImageIO as oiio

    from ..atomic import atomic_path

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    manifest = []
    for pair in pairs:
        write_exr(folder / f"{pair.name}.truth.exr", pair.truth, pair.colour_space,
                  {"gaslight:curve": pair.curve, "gaslight:exposure": pair.exposure,
                   "gaslight:light_truth": int(pair.light_truth),
                   "gaslight:units": "relative radiance, 1.0 = LDR white"})
        png = folder / f"{pair.name}.ldr.png"
        with atomic_path(png) as tmp:
            buf = oiio.ImageBuf(np.ascontiguousarray(pair.ldr))
            if not buf.write(str(tmp), "uint8"):
                raise OSError(f"cannot write {png}: {buf.geterror()}")
        manifest.append({"name": pair.name, **{k: v for k, v in vars(pair.spec).items()},
                         "exposure": pair.exposure, "light_truth": pair.light_truth,
                         "clipped_fraction": pair.clipped_fraction})
    write_text(folder / "pairs.json", json.dumps(manifest, indent=2, default=str))
    return folder
