"""What a camera's auto-exposure bracketing makes of real scenes: a folder of JPEGs.

Each *position* is a real HDR view (a perspective crop of a shared panorama,
or a truth view of the bundled example) shot as one bracket: the camera meters
the middle exposure so that the brightest frame clips ``clip_fraction`` of its
pixels, steps the shutter by ``step`` stops in the camera's frame order (most
cameras: 0, -, +), and writes 8-bit sRGB JPEGs whose EXIF carries the
*nominal* shutter speed (1/60 for 2^-6 s: real cameras round too),
FNumber, ISO and DateTimeOriginal + SubSecTimeOriginal. The brightest frame
is shot a little off (hand-held) and every frame carries photon and read
noise. Single photos of other views can be shot in between.

The truth of a position is ``truth`` in the working space Linear Rec.709;
an HDR view made from its photos at reference EV ``r`` (relative radiance as
:mod:`gaslight_usd.poses.views` defines it) should equal ``truth * gain * 2**r``
(:meth:`Position.expected`). Nothing derived is committed: tests and the bench
build shoots in a temporary folder.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

from ..atomic import atomic_path
from ..uplift.curves import SRGB

F_NUMBER = 8.0
MIDDLE_TIME = 2.0 ** -7
"""True time of every bracket's middle frame (labelled 1/125)."""
SHIFT = (1.0, -1.5)
"""Hand-held offset of the brightest frame, pixels (dy, dx)."""
ISO = 100
NOMINAL_SHUTTERS = (
    1 / 8000, 1 / 6400, 1 / 5000, 1 / 4000, 1 / 3200, 1 / 2500, 1 / 2000, 1 / 1600,
    1 / 1250, 1 / 1000, 1 / 800, 1 / 640, 1 / 500, 1 / 400, 1 / 320, 1 / 250, 1 / 200,
    1 / 160, 1 / 125, 1 / 100, 1 / 80, 1 / 60, 1 / 50, 1 / 40, 1 / 30, 1 / 25, 1 / 20,
    1 / 15, 1 / 13, 1 / 10, 1 / 8, 1 / 6, 1 / 5, 1 / 4, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0, 1.3,
    1.6, 2.0, 2.5, 3.2, 4.0, 5.0, 6.0, 8.0, 10.0, 13.0, 15.0, 20.0, 25.0, 30.0)
"""Shutter speeds as cameras label them (1/3-stop series)."""


def nominal_shutter(seconds: float) -> float:
    """The label a camera writes for a true exposure time (nearest in stops)."""
    table = np.asarray(NOMINAL_SHUTTERS)
    return float(table[np.argmin(np.abs(np.log2(table / seconds)))])


@dataclass
class Frame:
    path: Path
    true_time: float
    """Seconds the sensor was exposed (2^k/3); EXIF holds its nominal label."""
    taken: datetime


@dataclass
class Position:
    """One bracket of one view, or a single photo, and the radiance behind it."""

    name: str
    truth: np.ndarray
    frames: list[Frame] = field(default_factory=list)
    gain: float = 1.0
    """Encoded linear value = truth * gain * true_time (before clipping)."""

    @property
    def photos(self) -> list[Path]:
        return [f.path for f in self.frames]

    def expected(self, reference_ev: float) -> np.ndarray:
        """The HDR view the photos should give, at the set's reference EV (see module doc)."""
        return self.truth * np.float32(self.gain * F_NUMBER ** 2 * (100 / ISO)
                                       * 2.0 ** reference_ev)

    def seen(self) -> np.ndarray:
        """(H, W) pixels some frame saw: not black in the brightest, not clipped in the darkest."""
        lum = self.truth.max(axis=-1) * self.gain
        times = [f.true_time for f in self.frames]
        return (lum * max(times) > 0.01) & (lum * min(times) < 0.9)


def write_photo(path: Path, encoded: np.ndarray, exposure_time: float, taken: datetime | None,
                f_number: float = F_NUMBER, iso: int = ISO) -> Path:
    """An 8-bit JPEG with EXIF exposure and capture time, written by OpenImageIO."""
    u8 = np.round(np.clip(encoded, 0, 1) * 255).astype(np.uint8)
    h, w, c = u8.shape
    spec = oiio.ImageSpec(w, h, c, oiio.UINT8)
    spec.attribute("ExposureTime", float(exposure_time))
    spec.attribute("FNumber", float(f_number))
    spec.attribute("Exif:ISOSpeedRatings", int(iso))
    if taken is not None:
        spec.attribute("Exif:DateTimeOriginal", taken.strftime("%Y:%m:%d %H:%M:%S"))
        spec.attribute("Exif:SubsecTimeOriginal", f"{taken.microsecond // 10000:02d}")
    spec.attribute("Compression", "jpeg:95")
    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(str(tmp))
        if out is None or not out.open(str(tmp), spec):
            raise OSError(f"cannot write {path}: {oiio.geterror()}")
        out.write_image(np.ascontiguousarray(u8))
        out.close()
    return path


def metered_time(truth: np.ndarray, brightest_stops: float, clip_fraction: float) -> float:
    """Middle-frame exposure time (on the 1/3-stop grid) that clips ``clip_fraction``
    of the brightest frame, ``brightest_stops`` above it, at unit gain."""
    level = float(np.quantile(truth.max(axis=-1), 1.0 - clip_fraction))
    t_bright = 1.15 / max(level, 1e-9)
    t = t_bright / 2.0 ** brightest_stops
    return 2.0 ** (math.ceil(3 * math.log2(t)) / 3)


def expose(truth: np.ndarray, seconds: float, rng: np.random.Generator,
           shift: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """Encoded sRGB frame: shifted, exposed, photon + read noise, clipped, 8-bit."""
    from ..uplift.bracket import apply_shift

    linear = apply_shift(truth, shift) * np.float32(seconds)
    noisy = linear + rng.normal(0.0, 1.0, linear.shape).astype(np.float32) * np.sqrt(
        np.float32(2e-5) * np.maximum(linear, 0) + np.float32(1e-6))
    return np.round(SRGB.to_encoded(np.clip(noisy, 0, 1)) * 255) / 255


@dataclass
class Shoot:
    folder: Path
    positions: list[Position]
    singles: list[Position]


def shoot_bracket(position: Position, folder: Path, names: list[str], offsets: list[float],
                  start: datetime, rng: np.random.Generator, clip_fraction: float = 0.62,
                  gap_s: float = 0.3, capture_time: bool = True) -> datetime:
    """Shoot ``position`` as a bracket (EV ``offsets`` in camera order); returns the end time."""
    # the scene's brightness sets aperture/ISO: scale it so the middle frame is 1/125 s
    position.gain = metered_time(position.truth, max(offsets), clip_fraction) / MIDDLE_TIME
    t_mid = MIDDLE_TIME
    brightest = int(np.argmax(offsets))
    when = start
    for k, (name, off) in enumerate(zip(names, offsets, strict=True)):
        true_time = t_mid * 2.0 ** off
        shift = SHIFT if k == brightest else (0.0, 0.0)
        enc = expose(position.truth * np.float32(position.gain), true_time, rng, shift)
        path = write_photo(folder / name, enc, nominal_shutter(true_time),
                           when if capture_time else None)
        position.frames.append(Frame(path, true_time, when))
        when = when + timedelta(seconds=true_time + gap_s)
    return when


def aeb_shoot(scenes: list[np.ndarray], folder: Path, single_scenes: list[np.ndarray],
              seed: int = 0, capture_time: bool = True,
              patterns: tuple[tuple[float, ...], ...] = (
                  (0, -2, 2), (0, -2, 2), (0, -2, 2), (-4, -2, 0, 2, 4), (0, -3, 3, -6, 6)),
              ) -> Shoot:
    """A folder as a photographer leaves it: one bracket per scene, singles between.

    Frames are named IMG_0001.jpg ... in shooting order. The first single is
    shot 0.2 s after the second bracket, one step darker than its darkest frame
    (so EXIF alone would join it: only its image tells it apart); the others
    come 20 s after everything else.
    """
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    when = datetime(2026, 11, 24, 10, 0, 0)
    counter = iter(range(1, 10_000))
    positions: list[Position] = []
    singles: list[Position] = []
    for i, truth in enumerate(scenes):
        offsets = list(patterns[i % len(patterns)])
        pos = Position(f"position{i + 1}", truth)
        names = [f"IMG_{next(counter):04d}.jpg" for _ in offsets]
        when = shoot_bracket(pos, folder, names, offsets, when, rng,
                             capture_time=capture_time)
        positions.append(pos)
        if i == 1 and single_scenes:  # a lone frame right after the bracket
            low = min(pos.frames, key=lambda f: f.true_time)
            step = sorted(offsets)[1] - sorted(offsets)[0]
            single = Position("single1", single_scenes[0], gain=pos.gain)
            t = low.true_time / 2.0 ** step
            when += timedelta(seconds=0.2)
            enc = expose(single.truth * np.float32(single.gain), t, rng)
            path = write_photo(folder / f"IMG_{next(counter):04d}.jpg", enc,
                               nominal_shutter(t), when if capture_time else None)
            single.frames.append(Frame(path, t, when))
            singles.append(single)
        when += timedelta(seconds=6)
    for truth in single_scenes[1:]:
        when += timedelta(seconds=20)
        single = Position(f"single{len(singles) + 1}", truth)
        single.gain = metered_time(truth, 0.0, 0.05) / MIDDLE_TIME
        t = MIDDLE_TIME
        path = write_photo(folder / f"IMG_{next(counter):04d}.jpg",
                           expose(truth * np.float32(single.gain), t, rng),
                           nominal_shutter(t), when if capture_time else None)
        single.frames.append(Frame(path, t, when))
        singles.append(single)
    return Shoot(folder, positions, singles)


def panorama_scenes(count: int, width: int = 160, height: int = 120, fov: float = 70.0,
                    folder: Path | None = None) -> list[np.ndarray]:
    """Perspective crops of the shared unclipped panoramas, turning around each."""
    from .reference import load_source, look_camera, perspective_crop, shared_hdri_dir

    folder = Path(folder) if folder else shared_hdri_dir()
    names = ("forest", "sunset", "courtyard", "night")
    sources = [load_source(folder / f"{n}.exr") for n in names]
    scenes = []
    for i in range(count):
        src = sources[i % len(sources)]
        cam = look_camera(47.0 * i + 10.0, 5.0, fov, width, height)
        scenes.append(perspective_crop(src.pixels, cam))
    return scenes


def room_scenes(indices: list[int], width: int = 160, height: int = 120,
                example: Path | None = None) -> list[np.ndarray]:
    """Truth views of the bundled example (rendered radiance), downsampled."""
    from ..imageio import read_image
    from ..locate import example_room
    from .resample import area_resize

    folder = (Path(example) if example else example_room()) / "truth"
    return [area_resize(read_image(folder / f"view_{i:02d}.exr").pixels, height, width)
            for i in indices]
