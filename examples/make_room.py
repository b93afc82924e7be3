#!/usr/bin/env python3
"""Generate the bundled example scene ``examples/room/`` with Mitsuba 3.

A small interior set (5 m x 3 m x 4 m room, textured walls, a few objects, a bright
pendant lamp and a cool window) is path traced into:

* ``photos/view_NN.jpg``: LDR photos as a camera gives them (auto-exposed, clipped,
  sRGB OETF, 8-bit JPEG with EXIF ExposureTime / FNumber / ISO);
* ``truth/view_NN.exr``: the matching absolute linear Rec.709 radiance (half EXR);
* ``sparse/0/*.txt``: the true poses as a COLMAP text model;
* ``probes/probe_N.exr`` + ``probes/probes.json``: lat-long HDR panoramas;
* ``scene.json``: every number a test needs; ``digests.json``: SHA-256 of every
  generated file (the output is bit-for-bit reproducible from ``--seed``).

Usage::

    python examples/make_room.py [--seed 0] [--out DIR]
    python examples/make_room.py --verify [--out DIR]   # checks only, no rendering
    python examples/make_room.py --variant bulb --out DIR  # another room (see VARIANTS)

``--variant`` renders rooms the project was never tuned on (other lights, other
albedos, fewer and smaller photos) for ``gaslight2usd bench --suite chain``; the
default variant ``room`` is the bundled example, bit for bit.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import OpenImageIO as oiio

# --------------------------------------------------------------------------- constants

WIDTH, HEIGHT = 480, 360  # photo size (pixels)
HFOV_DEG = 65.0  # horizontal field of view of the pinhole cameras
N_VIEWS = 14  # the level ring across the room
N_UP_VIEWS = 6  # pitched up at the ceiling (the light every probe's upper half sees)
N_DOWN_VIEWS = 4  # pitched down at the floor around the probes
SPP = 48  # samples per pixel for the photos / truth EXRs (stratified 8 x 6)
BATCH = 8  # samples per pixel traced in one wavefront
PROBE_W, PROBE_H = 512, 256
PROBE_SPP = 32
MAX_DEPTH = 6  # path tracer depth (direct + 4 indirect bounces)
RR_DEPTH = 5  # Russian roulette starts at this depth

# Camera model: photo_linear = radiance * ExposureTime * K (then clip, OETF, 8 bit).
K_EXPOSURE = 10.0  # 1 / (s * radiance unit), valid for FNUMBER and ISO below
FNUMBER = 4.0
ISO = 100
SENSOR_WIDTH_MM = 36.0  # nominal, only used for the EXIF focal length
TARGET_MEDIAN = 0.2  # auto-exposure: median photo luminance (linear) before rounding
JPEG_QUALITY = 93
EXR_DATETIME = "2025:01:01 00:00:00"  # fixed so that EXR files are reproducible

ROOM_MIN = np.array([-2.5, 0.0, -2.0])  # metres, +Y up, origin = floor centre
ROOM_MAX = np.array([2.5, 3.0, 2.0])

LAMP_CENTER = np.array([-0.6, 2.0, 0.4])
LAMP_RADIUS = 0.05
LAMP_RADIANCE = 2500.0 * np.array([1.0, 0.72, 0.42])  # warm bare bulb
WINDOW_CENTER = np.array([ROOM_MAX[0] - 0.002, 1.6, 0.2])
WINDOW_HALF = (0.7, 0.55)  # half width (along z), half height (along y)
WINDOW_RADIANCE = 12.0 * np.array([0.78, 0.88, 1.0])  # cool daylight
LAMP_ON = True  # the variants may light the room without the pendant lamp
CEILING_PANELS: list[dict[str, Any]] = []  # extra emitters: {"center", "half", "radiance"}
SHADE: dict[str, Any] | None = None  # an open cylinder around the lamp: {"radius", "y0", "y1"}
# where the frames from below a shaded lamp stand, from the bulb (metres): the README's
# advice for a bulb in a shade ("Shooting the lights"), two frames from two places, whose
# sight lines cross at the bulb; the shade's opening shows the bulb from both
BELOW_OFFSETS = (np.array([0.3, -0.65, 0.2]), np.array([-0.25, -0.65, -0.25]))
TEXTURE_GAIN = 1.0  # albedo scale of every texture (then clipped to [0.02, 0.9])
SUN: dict[str, Any] | None = None  # a sun patch on the floor: {"min", "max", "radiance"}
# ("radiance": the sunlight's irradiance / pi, times the floor's albedo)
CAMERA_SPREAD = 1.0  # scale of the camera rings' radii (a larger room is shot from wider)

# No two shapes touch: Embree resolves exactly equal hit distances in an order that can
# change from one scene build to the next, so shared edges would make renders flip a few
# samples between runs. Objects float GAP above their supports; room surfaces overlap
# like shingles (see scene_dict).
GAP = 5e-4  # metres
OVERLAP = 0.05  # metres, how far the walls reach past the room
EMITTER_WEIGHTS = (3.0, 1.0)  # next-event estimation: how often lamp / window are picked
PROBE_POSITIONS = np.array([[0.0, 1.5, 0.0], [1.5, 1.2, -1.0], [-1.5, 1.0, 1.2]])

REC709_CHROMATICITIES = (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290)
LUMA = np.array([0.2126, 0.7152, 0.0722])
LLVM_DIRS = ("/usr/lib/x86_64-linux-gnu", "/usr/lib/llvm-19/lib")
LLVM_NAMES = ("libLLVM-19.so", "libLLVM.so.19.1", "libLLVM.so.19", "libLLVM-19.so.1")

_SMALL = {"WIDTH": 320, "HEIGHT": 240, "N_VIEWS": 12, "N_UP_VIEWS": 4, "N_DOWN_VIEWS": 2,
          "SPP": 32, "PROBE_W": 256, "PROBE_H": 128}
VARIANTS: dict[str, dict[str, Any]] = {
    # the bundled example
    "room": {},
    # a small, very bright bare bulb low in the room; a small dim window; darker albedos
    "bulb": _SMALL | {
        "LAMP_CENTER": np.array([1.2, 0.95, 1.1]), "LAMP_RADIUS": 0.025,
        "LAMP_RADIANCE": 15000.0 * np.array([1.0, 0.8, 0.55]),
        "WINDOW_HALF": (0.45, 0.4), "WINDOW_RADIANCE": 6.0 * np.array([0.8, 0.9, 1.0]),
        "TEXTURE_GAIN": 0.6,
        "PROBE_POSITIONS": np.array([[0.0, 1.4, 0.0], [0.85, 1.2, 0.75], [2.0, 1.6, 0.2]]),
    },
    # two ceiling panels and a bright window, no pendant; lighter albedos
    "panels": _SMALL | {
        "LAMP_ON": False,
        "CEILING_PANELS": [
            {"center": [-1.2, 2.995, -0.6], "half": (0.2, 0.2),
             "radiance": [320.0, 300.0, 260.0]},
            {"center": [1.0, 2.995, 0.9], "half": (0.2, 0.2),
             "radiance": [320.0, 300.0, 260.0]},
        ],
        "WINDOW_RADIANCE": 30.0 * np.array([0.78, 0.88, 1.0]), "TEXTURE_GAIN": 1.2,
        "PROBE_POSITIONS": np.array([[0.0, 1.4, 0.0], [-1.2, 2.5, -0.6], [2.0, 1.6, 0.2]]),
    },
    # a pendant bulb inside an open lampshade (seen through the shade's ends only)
    "shade": _SMALL | {
        "LAMP_CENTER": np.array([0.8, 2.1, 0.9]), "LAMP_RADIUS": 0.04,
        "LAMP_RADIANCE": 6000.0 * np.array([1.0, 0.75, 0.45]),
        "SHADE": {"radius": 0.16, "y0": 2.0, "y1": 2.26},
        "PROBE_POSITIONS": np.array([[0.0, 1.4, 0.0], [0.8, 1.6, 0.9], [2.0, 1.6, 0.2]]),
    },
    # no lamp: a bright window and a sun patch on the floor below it, three times as bright
    # as the window (a lit surface the photos clip, not a light); four floor views, so
    # that two photos frame the patch whole
    "sun": _SMALL | {
        "N_DOWN_VIEWS": 4,
        "LAMP_ON": False, "WINDOW_RADIANCE": 20.0 * np.array([0.75, 0.87, 1.0]),
        "SUN": {"min": [-0.45, 0.05], "max": [0.45, 0.85],
                "radiance": 150.0 * np.array([1.0, 0.9, 0.72])},
        "PROBE_POSITIONS": np.array([[0.0, 1.4, 0.0], [0.0, 0.6, 0.45], [2.0, 1.6, 0.2]]),
    },
    # a larger hall (7 m x 3.4 m x 5.4 m), a wide window, a lamp in the far corner, shot
    # from wider rings
    "hall": _SMALL | {
        "ROOM_MIN": np.array([-3.5, 0.0, -2.7]), "ROOM_MAX": np.array([3.5, 3.4, 2.7]),
        "LAMP_CENTER": np.array([-2.0, 2.3, -1.2]), "LAMP_RADIUS": 0.04,
        "LAMP_RADIANCE": 5000.0 * np.array([1.0, 0.78, 0.5]),
        "WINDOW_HALF": (0.9, 0.6), "WINDOW_RADIANCE": 15.0 * np.array([0.8, 0.9, 1.0]),
        "TEXTURE_GAIN": 0.8, "CAMERA_SPREAD": 1.35,
        "PROBE_POSITIONS": np.array([[0.0, 1.4, 0.0], [-1.6, 2.0, -0.9], [3.0, 1.6, 0.2]]),
    },
}
"""Rooms for ``--variant``: overrides of this module's constants (``room``: none)."""


def apply_variant(name: str) -> None:
    """Set this module's constants to variant ``name`` (see :data:`VARIANTS`)."""
    if name not in VARIANTS:
        raise SystemExit(f"unknown variant {name!r}; choose from {', '.join(VARIANTS)}")
    g = globals()
    g.update(VARIANTS[name])
    g["WINDOW_CENTER"] = np.array([g["ROOM_MAX"][0] - 0.002, 1.6, 0.2])
    g["VARIANT"] = name


VARIANT = "room"


def light_list() -> list[dict[str, Any]]:
    """Every emitter of the room, as ``scene.json`` lists it for the variants."""
    lights: list[dict[str, Any]] = []
    if LAMP_ON:
        lights.append({"name": "lamp", "kind": "sphere", "center": LAMP_CENTER.tolist(),
                       "radius": LAMP_RADIUS, "radiance": LAMP_RADIANCE.tolist(),
                       "shaded": SHADE is not None})
    for k, panel in enumerate(CEILING_PANELS):
        c, (hx, hz) = np.array(panel["center"]), panel["half"]
        corners = [c + [sx * hx, 0, sz * hz] for sx, sz in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
        lights.append({"name": f"panel_{k}", "kind": "rectangle", "center": c.tolist(),
                       "corners": [p.tolist() for p in corners], "normal": [0.0, -1.0, 0.0],
                       "radiance": list(panel["radiance"])})
    lights.append({"name": "window", "kind": "rectangle", "center": WINDOW_CENTER.tolist(),
                   "corners": window_corners().tolist(), "normal": [-1.0, 0.0, 0.0],
                   "radiance": WINDOW_RADIANCE.tolist()})
    return lights


mi: Any = None  # mitsuba module, set by init_mitsuba()
dr: Any = None  # drjit module


def log(msg: str) -> None:
    """Print a progress line."""
    print(msg, flush=True)


# --------------------------------------------------------------------------- mitsuba


def init_mitsuba() -> str:
    """Import Mitsuba, preferring ``llvm_ad_rgb`` (libLLVM 19), else ``scalar_rgb``."""
    global mi, dr
    if not os.environ.get("DRJIT_LIBLLVM_PATH"):
        for d in LLVM_DIRS:
            found = [Path(d) / n for n in LLVM_NAMES if (Path(d) / n).exists()]
            if found:
                os.environ["DRJIT_LIBLLVM_PATH"] = str(found[0])
                break
    import drjit
    import mitsuba

    mi, dr = mitsuba, drjit
    if os.environ.get("DRJIT_LIBLLVM_PATH") and dr.has_backend(dr.JitBackend.LLVM):
        mi.set_variant("llvm_ad_rgb")
        return "llvm_ad_rgb"
    warnings.warn(
        "libLLVM 19 not found (apt-get install libllvm19 or set DRJIT_LIBLLVM_PATH): "
        "falling back to the slow scalar_rgb variant; outputs will not match digests.json",
        stacklevel=2,
    )
    mi.set_variant("scalar_rgb")
    return "scalar_rgb"


def seed_for(*keys: int) -> int:
    """A 32-bit seed derived deterministically from integer keys."""
    return int(np.random.SeedSequence(list(keys)).generate_state(1)[0])


# --------------------------------------------------------------------------- textures


def value_noise(
    rng: np.random.Generator, shape: tuple[int, int], cells: tuple[int, int]
) -> np.ndarray:
    """Smooth value noise in [0, 1]: a random (cells+1) grid, smoothstep-interpolated."""
    h, w = shape
    gy, gx = cells
    grid = rng.random((gy + 1, gx + 1))
    y = (np.arange(h) + 0.5) * gy / h
    x = (np.arange(w) + 0.5) * gx / w
    y0 = np.minimum(y.astype(int), gy - 1)
    x0 = np.minimum(x.astype(int), gx - 1)
    fy = y - y0
    fx = x - x0
    fy = (fy * fy * (3 - 2 * fy))[:, None]
    fx = (fx * fx * (3 - 2 * fx))[None, :]
    a = grid[y0][:, x0]
    b = grid[y0][:, x0 + 1]
    c = grid[y0 + 1][:, x0]
    d = grid[y0 + 1][:, x0 + 1]
    return (a * (1 - fx) + b * fx) * (1 - fy) + (c * (1 - fx) + d * fx) * fy


def fbm(
    rng: np.random.Generator, shape: tuple[int, int], base: int, octaves: int = 5
) -> np.ndarray:
    """Fractal (multi-octave) value noise normalised to [0, 1]."""
    h, w = shape
    out = np.zeros(shape)
    for k in range(octaves):
        n = base * 2**k
        cells = (max(1, round(n * h / max(h, w))), max(1, round(n * w / max(h, w))))
        out += 0.5**k * value_noise(rng, shape, cells)
    return (out - out.min()) / (np.ptp(out) + 1e-12)


def rand_colour(rng: np.random.Generator, lo: float = 0.05, hi: float = 0.8) -> np.ndarray:
    """A random linear albedo colour."""
    return lo + (hi - lo) * rng.random(3)


def base_layer(
    rng: np.random.Generator,
    shape: tuple[int, int],
    colour: np.ndarray,
    base: int = 4,
    amount: float = 0.5,
) -> np.ndarray:
    """A colour modulated by fractal noise (plaster, paint, stains)."""
    n = fbm(rng, shape, base)
    tint = 1.0 + 0.15 * (fbm(rng, shape, base * 2)[..., None] - 0.5) * rng.standard_normal(3)
    return colour * (1.0 - amount / 2 + amount * n)[..., None] * tint


def paint_ellipses(
    img: np.ndarray, rng: np.random.Generator, n: int, rmin: float, rmax: float, alpha: float = 1.0
) -> None:
    """Paint n random solid ellipses (radii in pixels) in place."""
    h, w, _ = img.shape
    for _ in range(n):
        cy, cx = rng.random() * h, rng.random() * w
        ry, rx = rng.uniform(rmin, rmax, 2)
        colour = rand_colour(rng)
        y0, y1 = int(max(cy - ry, 0)), int(min(cy + ry + 1, h))
        x0, x1 = int(max(cx - rx, 0)), int(min(cx + rx + 1, w))
        yy, xx = np.mgrid[y0:y1, x0:x1]
        mask = ((yy + 0.5 - cy) / ry) ** 2 + ((xx + 0.5 - cx) / rx) ** 2 <= 1.0
        region = img[y0:y1, x0:x1]
        region[mask] = (1 - alpha) * region[mask] + alpha * colour


def paint_posters(img: np.ndarray, rng: np.random.Generator, n: int, smin: int, smax: int) -> None:
    """Paint n random posters: a frame around a grid of random colour cells plus a disc."""
    h, w, _ = img.shape
    for _ in range(n):
        ph, pw = rng.integers(smin, smax, 2)
        ph, pw = min(ph, h - 2), min(pw, w - 2)
        y0, x0 = rng.integers(0, h - ph), rng.integers(0, w - pw)
        cells = rng.integers(2, 9, 2)
        grid = 0.03 + 0.8 * rng.random((cells[0], cells[1], 3))
        iy = (np.arange(ph) * cells[0] // ph)[:, None]
        ix = (np.arange(pw) * cells[1] // pw)[None, :]
        poster = grid[iy, ix]
        yy, xx = np.mgrid[0:ph, 0:pw]
        disc = (yy - ph * rng.random()) ** 2 + (xx - pw * rng.random()) ** 2 < (
            0.25 * min(ph, pw) * (0.5 + rng.random())
        ) ** 2
        poster[disc] = rand_colour(rng)
        border = max(2, min(ph, pw) // 20)
        frame = np.ones((ph, pw), bool)
        frame[border:-border, border:-border] = False
        poster[frame] = rand_colour(rng, 0.02, 0.3)
        img[y0 : y0 + ph, x0 : x0 + pw] = poster


def tiles(
    rng: np.random.Generator,
    shape: tuple[int, int],
    tile: int,
    colour: np.ndarray,
    brick: bool = False,
    grout: int = 3,
) -> np.ndarray:
    """Tiles (or running-bond bricks) with per-tile colour jitter and dark grout."""
    h, w = shape
    th = tile // 2 if brick else tile
    yy, xx = np.mgrid[0:h, 0:w]
    row = yy // th
    shift = (row % 2) * (tile // 2) if brick else 0
    col = (xx + shift) // tile
    jitter = 0.6 + 0.8 * rng.random((row.max() + 2, col.max() + 2, 3))
    img = colour * jitter[row, col] * (0.8 + 0.4 * fbm(rng, shape, 16))[..., None]
    lines = ((yy % th) < grout) | (((xx + shift) % tile) < grout)
    img[lines] = 0.6 * colour.mean() * np.array([0.5, 0.5, 0.5])
    return img


def stripes(rng: np.random.Generator, shape: tuple[int, int], n: int) -> np.ndarray:
    """Vertical wallpaper stripes of random widths and colours, lightly noisy."""
    h, w = shape
    edges = np.sort(rng.integers(0, w, n))
    band = np.searchsorted(edges, np.arange(w))
    colours = np.stack([rand_colour(rng, 0.15, 0.75) for _ in range(n + 1)])
    img = np.broadcast_to(colours[band][None], (h, w, 3)).copy()
    return img * (0.85 + 0.3 * fbm(rng, shape, 8))[..., None]


def wood(rng: np.random.Generator, shape: tuple[int, int], colour: np.ndarray) -> np.ndarray:
    """Wood-like grain: warped stripes along x."""
    h, w = shape
    warp = fbm(rng, shape, 4)
    y = np.arange(h)[:, None] / h
    grain = 0.5 + 0.5 * np.sin(2 * np.pi * (18 * y + 3 * warp))
    return colour * (0.6 + 0.5 * grain * (0.7 + 0.6 * fbm(rng, shape, 32)))[..., None]


def make_textures(rng: np.random.Generator) -> dict[str, np.ndarray]:
    """All surface albedo textures (linear RGB, float32, row 0 = top)."""
    px = 250  # texture pixels per metre on the room shell (4 mm per pixel)
    t: dict[str, np.ndarray] = {}
    shape_x = (int(3 * px), int(5 * px))  # walls facing +-z: 5 m wide, 3 m high
    shape_z = (int(3 * px), int(4 * px))  # walls facing +-x: 4 m wide, 3 m high
    shape_f = (int(4 * px), int(5 * px))  # floor / ceiling

    t["wall_back"] = stripes(rng, shape_x, 40)
    paint_posters(t["wall_back"], rng, 7, 90, 260)
    paint_ellipses(t["wall_back"], rng, 30, 8, 40, alpha=0.7)

    t["wall_front"] = base_layer(rng, shape_x, np.array([0.55, 0.5, 0.42]))
    paint_ellipses(t["wall_front"], rng, 60, 10, 70)
    paint_posters(t["wall_front"], rng, 8, 80, 240)

    t["wall_left"] = tiles(rng, shape_z, 60, np.array([0.5, 0.25, 0.17]), brick=True)
    paint_posters(t["wall_left"], rng, 4, 90, 220)

    t["wall_right"] = base_layer(rng, shape_z, np.array([0.42, 0.5, 0.46]))
    paint_ellipses(t["wall_right"], rng, 50, 6, 50, alpha=0.85)
    paint_posters(t["wall_right"], rng, 5, 70, 180)

    t["floor"] = tiles(rng, shape_f, 100, np.array([0.35, 0.3, 0.25]))
    paint_ellipses(t["floor"], rng, 40, 5, 30, alpha=0.5)

    t["ceiling"] = base_layer(rng, shape_f, np.array([0.7, 0.7, 0.68]), base=3, amount=0.3)
    paint_posters(t["ceiling"], rng, 6, 60, 160)
    paint_ellipses(t["ceiling"], rng, 25, 5, 30, alpha=0.6)

    t["table"] = wood(rng, (256, 512), np.array([0.45, 0.28, 0.14]))
    t["cabinet"] = wood(rng, (512, 256), np.array([0.3, 0.2, 0.12]))
    paint_posters(t["cabinet"], rng, 3, 40, 120)
    t["crate"] = tiles(rng, (256, 256), 64, np.array([0.2, 0.45, 0.3]))
    paint_ellipses(t["crate"], rng, 10, 5, 20)
    t["box"] = base_layer(rng, (128, 128), np.array([0.7, 0.6, 0.15]))
    paint_posters(t["box"], rng, 3, 20, 60)
    t["ball_red"] = base_layer(rng, (128, 256), np.array([0.7, 0.08, 0.06]), base=8)
    paint_ellipses(t["ball_red"], rng, 12, 4, 12)
    t["ball_blue"] = stripes(rng, (128, 256), 12) * np.array([0.4, 0.6, 1.0])
    if TEXTURE_GAIN != 1.0:
        t = {k: v * TEXTURE_GAIN for k, v in t.items()}
    return {k: np.clip(v, 0.02, 0.9).astype(np.float32) for k, v in t.items()}


# --------------------------------------------------------------------------- geometry


def transform(centre: np.ndarray, axes: np.ndarray) -> list[list[float]]:
    """4x4 to-world matrix: columns are the scaled local x, y, z axes and the centre."""
    m = np.eye(4)
    m[:3, :3] = axes
    m[:3, 3] = centre
    return m.tolist()


def rect_axes(centre: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Axes of a Mitsuba rectangle ([-1,1]^2, normal +z) whose normal faces the room."""
    n = np.cross(u, v)
    inward = np.array([0.0, 1.5, 0.0]) - centre
    if n @ inward < 0:
        u = -u
        n = -n
    return np.stack([u, v, n / np.linalg.norm(n)], axis=1)


def box_axes(half: tuple[float, float, float], yaw_deg: float = 0.0) -> np.ndarray:
    """Axes of a Mitsuba cube ([-1,1]^3) scaled by half sizes and turned about +Y."""
    a = math.radians(yaw_deg)
    rot = np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])
    return rot @ np.diag(half)


def window_corners() -> np.ndarray:
    """The window's four corners (counter-clockwise seen from inside the room)."""
    hz, hy = WINDOW_HALF
    c = WINDOW_CENTER
    return np.array([c + [0, -hy, -hz], c + [0, -hy, hz], c + [0, hy, hz], c + [0, hy, -hz]])


def plain(rgb: tuple[float, float, float]) -> dict[str, Any]:
    """A two-sided diffuse material of one colour."""
    return {
        "type": "twosided",
        "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": rgb}},
    }


def scene_dict(tex: dict[str, np.ndarray]) -> dict[str, Any]:
    """The Mitsuba scene description."""

    def textured(name: str) -> dict[str, Any]:
        bitmap = {
            "type": "bitmap",
            "bitmap": mi.Bitmap(tex[name]),
            "raw": True,
            "filter_type": "bilinear",
            "wrap_mode": "repeat",
        }
        return {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": bitmap}}

    lo, hi = ROOM_MIN, ROOM_MAX
    mid = (lo + hi) / 2
    ex, ey, ez = (hi - lo) / 2
    # No two shapes touch (see GAP): floor and ceiling stop GAP short of the walls, the
    # walls facing +-x stop GAP short of those facing +-z, and walls reach OVERLAP past
    # the room so that the slits stay closed.
    g, o = GAP, OVERLAP
    shell = {
        "floor": ((mid[0], lo[1], mid[2]), (ex - g, 0, 0), (0, 0, ez - g)),
        "ceiling": ((mid[0], hi[1], mid[2]), (ex - g, 0, 0), (0, 0, ez - g)),
        "wall_back": ((mid[0], mid[1], lo[2]), (ex + o, 0, 0), (0, ey + o, 0)),
        "wall_front": ((mid[0], mid[1], hi[2]), (ex + o, 0, 0), (0, ey + o, 0)),
        "wall_left": ((lo[0], mid[1], mid[2]), (0, 0, ez - g), (0, ey + o, 0)),
        "wall_right": ((hi[0], mid[1], mid[2]), (0, 0, ez - g), (0, ey + o, 0)),
    }
    d: dict[str, Any] = {"type": "scene"}
    for name, (c, u, v) in shell.items():
        centre = np.array(c, float)
        axes = rect_axes(centre, np.array(u, float), np.array(v, float))
        d[name] = {
            "type": "rectangle",
            "to_world": mi.ScalarTransform4f(transform(centre, axes)),
            "bsdf": textured(name),
        }

    boxes = object_boxes()
    for name, (c, half, yaw, texname) in boxes.items():
        d[name] = {
            "type": "cube",
            "to_world": mi.ScalarTransform4f(transform(np.array(c), box_axes(half, yaw))),
            "bsdf": textured(texname),
        }
    for name, (centre, radius) in balls().items():
        d[name] = {"type": "sphere", "center": centre, "radius": radius,
                   "bsdf": textured(name)}
    if LAMP_ON:
        add_lamp(d, g)
    for k, panel in enumerate(CEILING_PANELS):
        hx, hz = panel["half"]
        axes = np.stack([[hx, 0, 0], [0, 0, hz], [0, -1.0, 0]], axis=1)  # normal -y
        d[f"panel_{k}"] = {
            "type": "rectangle",
            "to_world": mi.ScalarTransform4f(transform(np.array(panel["center"]), axes)),
            "bsdf": plain((0.0, 0.0, 0.0)),
            "emitter": {"type": "area", "sampling_weight": EMITTER_WEIGHTS[0],
                        "radiance": {"type": "rgb", "value": list(panel["radiance"])}},
        }
    add_window(d)
    if SUN is not None:
        f_centre, f_u, f_v = (np.array(x, float) for x in shell["floor"])
        add_sun(d, (f_centre, rect_axes(f_centre, f_u, f_v)), tex["floor"])
    return d


def object_boxes() -> dict[str, tuple[tuple[float, float, float], tuple[float, float, float],
                                       float, str]]:
    """The furniture: name -> centre, half sizes, yaw (degrees), texture; each floats GAP
    above what it stands on."""
    g, hi = GAP, ROOM_MAX
    table_top = 0.75 + g
    return {
        "table": ((0.5, 0.375 + g, -0.5), (0.6, 0.375, 0.4), 10.0, "table"),
        "cabinet": ((-1.5, 0.9 + g, -1.75 + g), (0.5, 0.9, 0.25), 0.0, "cabinet"),
        "crate": ((1.7, 0.25 + g, 1.4), (0.25, 0.25, 0.25), 20.0, "crate"),
        "box": ((0.3, table_top + 0.15 + g, -0.45), (0.15, 0.15, 0.15), -30.0, "box"),
        "sill": ((hi[0] - 0.06 - g, 1.02 - g, 0.2), (0.06, 0.03, 0.85), 0.0, "cabinet"),
    }


def balls() -> dict[str, tuple[list[float], float]]:
    """The two balls: name -> centre, radius (each floats GAP above what it stands on)."""
    g = GAP
    table_top = 0.75 + g
    return {"ball_red": ([-0.8, 0.3 + g, 1.3], 0.3),
            "ball_blue": ([0.9, table_top + 0.15 + g, -0.6], 0.15)}


def add_lamp(d: dict[str, Any], g: float) -> None:
    """The pendant lamp: a bare bulb on a cord (and the variants' shade around it)."""
    d["lamp"] = {
        "type": "sphere",
        "center": LAMP_CENTER.tolist(),
        "radius": LAMP_RADIUS,
        "bsdf": plain((0.0, 0.0, 0.0)),
        "emitter": {
            "type": "area",
            "sampling_weight": EMITTER_WEIGHTS[0],
            "radiance": {"type": "rgb", "value": LAMP_RADIANCE.tolist()},
        },
    }
    top = LAMP_CENTER + [0, LAMP_RADIUS + g, 0]
    cord_to = np.array([top[0], ROOM_MAX[1] - g, top[2]])
    d["cord"] = {
        "type": "cylinder",
        "p0": top.tolist(),
        "p1": cord_to.tolist(),
        "radius": 0.006,
        "bsdf": plain((0.03, 0.03, 0.03)),
    }
    if SHADE is not None:
        d["shade"] = {
            "type": "cylinder",
            "p0": [LAMP_CENTER[0], SHADE["y0"], LAMP_CENTER[2]],
            "p1": [LAMP_CENTER[0], SHADE["y1"], LAMP_CENTER[2]],
            "radius": SHADE["radius"],
            "bsdf": plain((0.75, 0.7, 0.6)),
        }


def add_window(d: dict[str, Any]) -> None:
    """The window: a one-sided rectangle emitter in the +x wall, facing into the room."""
    hz, hy = WINDOW_HALF
    win_axes = np.stack([[0, 0, hz], [0, hy, 0], [-1.0, 0, 0]], axis=1)  # normal -x
    d["window"] = {
        "type": "rectangle",
        "to_world": mi.ScalarTransform4f(transform(WINDOW_CENTER, win_axes)),
        "bsdf": plain((0.0, 0.0, 0.0)),
        "emitter": {
            "type": "area",
            "sampling_weight": EMITTER_WEIGHTS[1],
            "radiance": {"type": "rgb", "value": WINDOW_RADIANCE.tolist()},
        },
    }


def add_sun(d: dict[str, Any], floor: tuple[np.ndarray, np.ndarray], albedo: np.ndarray) -> None:
    """A sun patch: the floor where a sunbeam through the window lands, as a one-sided
    rectangle emitter a contact gap above the floor whose radiance is the floor's albedo
    texture x ``SUN["radiance"]`` (the sun's irradiance / pi), so the patch keeps the
    floor's pattern. Modelled as an emitter so that the path tracer's next-event
    estimation reaches it: a spot light's bounce off a small bright patch left every wall
    full of fireflies at these sample counts. It is not one of the scene's lights (a lit
    surface the photos clip), and no sun is in view.

    ``floor``: the floor rectangle's centre and axes (:func:`rect_axes`), whose UVs the
    patch's are mapped onto so that both read the same texels."""
    (x0, z0), (x1, z1) = SUN["min"], SUN["max"]
    centre = np.array([(x0 + x1) / 2, GAP, (z0 + z1) / 2])
    axes = np.stack([[(x1 - x0) / 2, 0, 0], [0, 0, -(z1 - z0) / 2], [0, 1.0, 0]], axis=1)
    f_centre, f_axes = floor
    # floor local coordinates (in [-1, 1]) of the patch's: affine, l_f = A l_p + b
    norms = (f_axes[:, :2] ** 2).sum(axis=0)
    a = (f_axes[:, :2].T @ axes[:, :2]) / norms[:, None]
    b = f_axes[:, :2].T @ (centre - f_centre) / norms
    to_uv = np.eye(3)  # uv = (l + 1) / 2 on both rectangles
    to_uv[:2, :2] = a
    to_uv[:2, 2] = 0.5 + 0.5 * b - 0.5 * a.sum(axis=1)
    radiance = (albedo * np.asarray(SUN["radiance"], np.float32)).astype(np.float32)
    d["sun_patch"] = {
        "type": "rectangle",
        "to_world": mi.ScalarTransform4f(transform(centre, axes)),
        "bsdf": plain((0.0, 0.0, 0.0)),
        "emitter": {"type": "area", "sampling_weight": EMITTER_WEIGHTS[0],
                    "radiance": {"type": "bitmap", "bitmap": mi.Bitmap(radiance), "raw": True,
                                 "filter_type": "bilinear",
                                 "to_uv": mi.ScalarTransform3f(to_uv.tolist())}},
    }


# --------------------------------------------------------------------------- cameras


@dataclass
class Camera:
    """A pinhole camera: centre and camera-to-world rotation (COLMAP axes x right, y down, z
    forward, as the columns of ``c2w``)."""

    centre: np.ndarray
    c2w: np.ndarray

    @property
    def w2c(self) -> np.ndarray:
        """World-to-camera rotation."""
        return self.c2w.T

    @property
    def t(self) -> np.ndarray:
        """COLMAP translation: x_cam = R @ x_world + t."""
        return -self.w2c @ self.centre


def intrinsics() -> tuple[float, float, float, float]:
    """Pinhole fx, fy, cx, cy in pixels (COLMAP convention: pixel centres at +0.5)."""
    f = (WIDTH / 2) / math.tan(math.radians(HFOV_DEG) / 2)
    return f, f, WIDTH / 2, HEIGHT / 2


def look_at(centre: np.ndarray, target: np.ndarray) -> Camera:
    """A level camera at ``centre`` looking at ``target`` (world up is +Y)."""
    fwd = target - centre
    fwd = fwd / np.linalg.norm(fwd)
    right = np.cross(fwd, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)
    return Camera(centre.astype(float), np.stack([right, down, fwd], axis=1))


def camera_loop(n: int) -> list[Camera]:
    """n cameras on an ellipse inside the room, looking across it with a slight turn."""
    cams = []
    for i in range(n):
        a = 2 * math.pi * i / n
        c = np.array([1.55 * CAMERA_SPREAD * math.cos(a), 1.4 + 0.15 * math.sin(2 * a),
                      1.1 * CAMERA_SPREAD * math.sin(a)])
        turn = a + math.pi + math.radians(15)
        target = c + np.array([math.cos(turn), 0.1 + 0.1 * math.cos(a), math.sin(turn)])
        cams.append(look_at(c, target))
    return cams


def camera_pitched(n: int, pitch_deg: float, radius: tuple[float, float], height: float,
                   phase: float) -> list[Camera]:
    """n cameras on a smaller ellipse, looking across the room pitched by ``pitch_deg``
    (up > 0): a set survey shoots the ceiling and the floor too, not only eye level."""
    cams = []
    rise = math.tan(math.radians(pitch_deg))
    for i in range(n):
        a = 2 * math.pi * (i + phase) / n
        c = np.array([radius[0] * CAMERA_SPREAD * math.cos(a), height,
                      radius[1] * CAMERA_SPREAD * math.sin(a)])
        turn = a + math.pi + math.radians(15)
        target = c + np.array([math.cos(turn), rise, math.sin(turn)])
        cams.append(look_at(c, target))
    return cams


def camera_rig() -> list[Camera]:
    """The example's photos: the level ring, then the ceiling and the floor views."""
    return (camera_loop(N_VIEWS)
            + camera_pitched(N_UP_VIEWS, 40.0, (1.2, 0.8), 1.5, 0.25)
            + camera_pitched(N_DOWN_VIEWS, -35.0, (1.2, 0.8), 1.6, 0.5))


def below_cameras() -> list[Camera]:
    """The frames from below a shaded lamp, looking up at its bulb through the opening."""
    return [look_at(LAMP_CENTER + offset, LAMP_CENTER) for offset in BELOW_OFFSETS]


def rot_to_quat(r: np.ndarray) -> np.ndarray:
    """Rotation matrix -> unit quaternion (w, x, y, z) with w >= 0."""
    m = r
    tr = np.trace(m)
    if tr > 0:
        s = 2 * math.sqrt(tr + 1)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2 * math.sqrt(1 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2 * math.sqrt(1 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s]
    else:
        s = 2 * math.sqrt(1 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s]
    q = np.array(q)
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def quat_to_rot(q: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) -> rotation matrix."""
    w, x, y, z = q / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def latlong_dirs(u: np.ndarray, v: np.ndarray, width: int, height: int) -> np.ndarray:
    """World directions of continuous lat-long image coordinates (pixel x covers [x, x+1))."""
    lon = -2 * np.pi * (u / width - 0.5)
    lat = np.pi * (0.5 - v / height)
    return np.stack([np.sin(lon) * np.cos(lat), np.sin(lat), np.cos(lon) * np.cos(lat)], -1)


def dir_to_latlong(d: np.ndarray, width: int, height: int) -> tuple[float, float]:
    """Inverse of ``latlong_dirs``: continuous (x, y) image coordinates of a direction."""
    d = d / np.linalg.norm(d)
    lon = math.atan2(d[0], d[2])
    lat = math.asin(d[1])
    return width * (0.5 - lon / (2 * np.pi)), height * (0.5 - lat / np.pi)


# --------------------------------------------------------------------------- rendering


class Renderer:
    """Path traces pinhole views and lat-long probes of one scene, deterministically.

    JIT variants trace our own rays through ``integrator.sample`` in wavefronts of
    ``BATCH`` samples per pixel and average them in numpy (float64, fixed order), so no
    atomic accumulation order can change the result. The scalar fallback uses
    ``mi.render`` (probes via six cube faces).
    """

    def __init__(self, tex: dict[str, np.ndarray], seed: int) -> None:
        self.seed = seed
        self.scene = mi.load_dict(scene_dict(tex))
        self.integrator = mi.load_dict(
            {"type": "path", "max_depth": MAX_DEPTH, "rr_depth": RR_DEPTH}
        )
        self.jit = not mi.variant().startswith("scalar")

    def _accumulate(self, npix: int, spp: int, key: tuple[int, ...], rays: Any) -> np.ndarray:
        """Mean radiance (npix, 3) of ``spp`` samples per pixel.

        ``rays(pix, jitter)`` makes the rays of pixels ``pix`` (UInt32) at sub-pixel
        positions ``jitter`` (Point2f in [0, 1)^2). Sub-pixel positions are stratified on
        a gx x gy grid, gx * gy = spp (sample s of every pixel uses stratum s).
        """
        assert spp % BATCH == 0, "spp must be a multiple of BATCH"
        gy = max(d for d in range(1, math.isqrt(spp) + 1) if spp % d == 0)
        gx = spp // gy
        total = np.zeros((npix, 3))
        sampler = mi.load_dict({"type": "independent"})
        n = npix * BATCH
        for p in range(spp // BATCH):
            sampler.seed(dr.opaque(mi.UInt32, seed_for(self.seed, *key, p)), n)
            idx = dr.arange(mi.UInt32, n)
            sample = idx // npix + dr.opaque(mi.UInt32, p * BATCH)
            stratum = mi.Point2f(mi.Float(sample % gx), mi.Float(sample // gx))
            ray = rays(idx % npix, (stratum + sampler.next_2d()) / mi.Point2f(gx, gy))
            radiance, _, _ = self.integrator.sample(self.scene, sampler, ray)
            arr = np.nan_to_num(np.array(radiance, dtype=np.float64), nan=0.0, posinf=0.0)
            total += arr.reshape(3, BATCH, npix).sum(axis=1).T
        return total / spp

    @staticmethod
    def _opaque3(v: np.ndarray, cls: Any) -> Any:
        return cls(*[dr.opaque(mi.Float, float(c)) for c in v])

    def pinhole(self, cam: Camera, index: int, spp: int) -> np.ndarray:
        """Radiance image (HEIGHT, WIDTH, 3) float32 of a pinhole camera."""
        fx, fy, cx, cy = intrinsics()
        if not self.jit:
            return self._perspective_scalar(cam, WIDTH, HEIGHT, HFOV_DEG, spp, index)
        right, down, fwd = (self._opaque3(cam.c2w[:, k], mi.Vector3f) for k in range(3))
        origin = self._opaque3(cam.centre, mi.Point3f)

        def rays(pix: Any, jit: Any) -> Any:
            x = mi.Float(pix % WIDTH) + jit.x
            y = mi.Float(pix // WIDTH) + jit.y
            d = right * ((x - cx) / fx) + down * ((y - cy) / fy) + fwd
            return mi.RayDifferential3f(origin, dr.normalize(d))

        img = self._accumulate(WIDTH * HEIGHT, spp, (1, index), rays)
        return img.reshape(HEIGHT, WIDTH, 3).astype(np.float32)

    def latlong(self, pos: np.ndarray, index: int, spp: int) -> np.ndarray:
        """Lat-long radiance panorama (PROBE_H, PROBE_W, 3) float32 seen from ``pos``."""
        if not self.jit:
            return self._latlong_scalar(pos, index, spp)
        origin = self._opaque3(pos, mi.Point3f)

        def rays(pix: Any, jit: Any) -> Any:
            lon = -2 * dr.pi * ((mi.Float(pix % PROBE_W) + jit.x) / PROBE_W - 0.5)
            lat = dr.pi * (0.5 - (mi.Float(pix // PROBE_W) + jit.y) / PROBE_H)
            d = mi.Vector3f(dr.sin(lon) * dr.cos(lat), dr.sin(lat), dr.cos(lon) * dr.cos(lat))
            return mi.RayDifferential3f(origin, d)

        img = self._accumulate(PROBE_W * PROBE_H, spp, (2, index), rays)
        return img.reshape(PROBE_H, PROBE_W, 3).astype(np.float32)

    # -- scalar fallback (slow, not bit-compatible with the JIT path)

    def _perspective_scalar(
        self, cam: Camera, w: int, h: int, fov: float, spp: int, index: int
    ) -> np.ndarray:
        to_world = mi.ScalarTransform4f().look_at(
            origin=cam.centre.tolist(),
            target=(cam.centre + cam.c2w[:, 2]).tolist(),
            up=(-cam.c2w[:, 1]).tolist(),
        )
        sensor = mi.load_dict(
            {
                "type": "perspective",
                "fov": fov,
                "fov_axis": "x",
                "to_world": to_world,
                "sampler": {"type": "independent", "sample_count": spp},
                "film": {
                    "type": "hdrfilm",
                    "width": w,
                    "height": h,
                    "pixel_format": "rgb",
                    "rfilter": {"type": "box"},
                },
            }
        )
        img = mi.render(
            self.scene,
            sensor=sensor,
            integrator=self.integrator,
            seed=seed_for(self.seed, 3, index),
            spp=spp,
        )
        return np.array(img, dtype=np.float32)[..., :3]

    def _latlong_scalar(self, pos: np.ndarray, index: int, spp: int) -> np.ndarray:
        size = PROBE_H
        axes = np.eye(3)
        faces, cams = [], []
        for k in range(6):
            fwd = axes[k // 2] * (1 if k % 2 == 0 else -1)
            up = np.array([0.0, 0.0, 1.0]) if k // 2 == 1 else np.array([0.0, 1.0, 0.0])
            cam = look_at(pos, pos + fwd) if k // 2 != 1 else _look_up(pos, fwd, up)
            cams.append(cam)
            faces.append(self._perspective_scalar(cam, size, size, 90.0, spp, 100 * index + k))
        yy, xx = np.mgrid[0:PROBE_H, 0:PROBE_W]
        d = latlong_dirs(xx + 0.5, yy + 0.5, PROBE_W, PROBE_H)
        local = np.stack([d @ c.c2w for c in cams])  # (6, H, W, 3) camera coordinates
        face = np.argmax(local[..., 2], axis=0)
        loc = np.take_along_axis(local, face[None, ..., None], axis=0)[0]
        u = np.clip(((loc[..., 0] / loc[..., 2] + 1) / 2 * size).astype(int), 0, size - 1)
        v = np.clip(((loc[..., 1] / loc[..., 2] + 1) / 2 * size).astype(int), 0, size - 1)
        return np.stack(faces)[face, v, u]


def _look_up(pos: np.ndarray, fwd: np.ndarray, up: np.ndarray) -> Camera:
    """A camera looking along +-Y (``look_at`` needs a non-vertical direction)."""
    right = np.cross(fwd, up)
    down = np.cross(fwd, right)
    return Camera(pos, np.stack([right, down, fwd], axis=1))


# --------------------------------------------------------------------------- photos & I/O


def srgb_oetf(x: np.ndarray) -> np.ndarray:
    """Piecewise sRGB encoding (IEC 61966-2-1) of linear values in [0, 1]."""
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def srgb_eotf(v: np.ndarray) -> np.ndarray:
    """Inverse of ``srgb_oetf``."""
    return np.where(v <= 0.04045, v / 12.92, np.power((v + 0.055) / 1.055, 2.4))


def auto_exposure(radiance: np.ndarray) -> float:
    """Exposure time putting the median luminance at TARGET_MEDIAN, rounded to 1/3 stop."""
    median = float(np.median(radiance @ LUMA))
    stops = round(3 * math.log2(TARGET_MEDIAN / (K_EXPOSURE * median))) / 3
    return 2.0**stops


def exif_roundtrip(t: float, tmpdir: Path) -> float:
    """ExposureTime as a reader gets it back from EXIF (OIIO stores a rational)."""
    path = tmpdir / ".exif_probe.jpg"
    spec = oiio.ImageSpec(8, 8, 3, oiio.UINT8)
    spec.attribute("ExposureTime", float(t))
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), spec)
    out.write_image(np.zeros((8, 8, 3), np.uint8))
    out.close()
    inp = oiio.ImageInput.open(str(path))
    value = float(inp.spec().getattribute("ExposureTime"))
    inp.close()
    path.unlink()
    return value


def photo_pixels(radiance: np.ndarray, exposure_time: float) -> np.ndarray:
    """What the camera records: clip(radiance * t * K), sRGB OETF, 8-bit."""
    linear = np.clip(radiance.astype(np.float64) * exposure_time * K_EXPOSURE, 0.0, 1.0)
    return np.round(srgb_oetf(linear) * 255).astype(np.uint8)


def _tmp_name(path: Path) -> Path:
    return path.with_name(f".{path.stem}.tmp{path.suffix}")


def write_image(path: Path, pixels: np.ndarray, attrs: dict[str, Any], fmt: Any) -> None:
    """Write an image atomically with OpenImageIO (attrs: name -> value or (type, value))."""
    h, w, c = pixels.shape
    spec = oiio.ImageSpec(w, h, c, fmt)
    for name, value in attrs.items():
        if isinstance(value, tuple):
            spec.attribute(name, oiio.TypeDesc(value[0]), value[1])
        else:
            spec.attribute(name, value)
    tmp = _tmp_name(path)
    out = oiio.ImageOutput.create(str(tmp))
    if out is None or not out.open(str(tmp), spec):
        raise RuntimeError(f"{path}: cannot write: {oiio.geterror()}")
    out.write_image(pixels)
    out.close()
    del out  # environment-map EXRs are only flushed when the output is destroyed
    os.replace(tmp, path)


def write_text(path: Path, text: str) -> None:
    """Write a text file atomically."""
    tmp = _tmp_name(path)
    tmp.write_text(text)
    os.replace(tmp, path)


def exr_attrs(note: str) -> dict[str, Any]:
    """Attributes common to every HDR EXR."""
    return {
        "compression": "zip",
        "chromaticities": ("float[8]", REC709_CHROMATICITIES),
        "oiio:ColorSpace": "lin_rec709_scene",
        "DateTime": EXR_DATETIME,
        "gaslight:units": "absolute scene radiance (renderer units), linear Rec.709 / D65",
        "gaslight:note": note,
    }


def write_colmap(folder: Path, cams: list[Camera]) -> None:
    """The true poses as a COLMAP text model (one PINHOLE camera, no 3D points)."""
    fx, fy, cx, cy = intrinsics()
    write_text(
        folder / "cameras.txt",
        (
            "# Camera list with one line of data per camera:\n"
            "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
            "# Number of cameras: 1\n"
            f"1 PINHOLE {WIDTH} {HEIGHT} {fx:.10f} {fy:.10f} {cx:.10f} {cy:.10f}\n"
        ),
    )
    lines = [
        "# Image list with two lines of data per image:",
        "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME",
        "#   POINTS2D[] as (X, Y, POINT3D_ID)",
        f"# Number of images: {len(cams)}, mean observations per image: 0",
    ]
    for i, cam in enumerate(cams):
        q = rot_to_quat(cam.w2c)
        vals = " ".join(f"{v:.12f}" for v in (*q, *cam.t))
        lines += [f"{i + 1} {vals} 1 view_{i:02d}.jpg", ""]
    write_text(folder / "images.txt", "\n".join(lines) + "\n")
    write_text(
        folder / "points3D.txt",
        (
            "# 3D point list with one line of data per point:\n"
            "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
            "# Number of points: 0, mean track length: 0\n"
        ),
    )


def sha256(path: Path) -> str:
    """Hex SHA-256 of a file."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


# --------------------------------------------------------------------------- generation


def generate(out: Path, seed: int, only: set[str] | None = None) -> None:
    """Render and write the whole example folder.

    A variant with a shaded lamp also gets ``extra/below_00.exr`` and ``below_01.exr``:
    the true radiance of two frames from below the lamp (:func:`below_cameras`), no
    photos; ``scene.json``'s ``extra_views`` poses them. They are not among the photos:
    the chain bench makes the darker frames the README's capture adds for the bulb from
    them (``gaslight_usd/bench/dark_frames.py``).

    ``only`` names the views and probes to render (file stems: ``view_03``,
    ``probe_1``, ``below_00``); every pixel's samples depend on its view's index alone, so
    each comes out as in a whole run. A partial run writes those files, the
    poses and their digests, not ``scene.json`` (its view list would be short).
    """
    if only is not None:  # before any folder is made: a wrong name leaves nothing behind
        names = {f"view_{i:02d}" for i in range(len(camera_rig()))} | {
            f"probe_{k}" for k in range(len(PROBE_POSITIONS))} | (
            {f"below_{j:02d}" for j in range(len(BELOW_OFFSETS))} if SHADE is not None
            else set())
        if only - names:
            raise SystemExit(f"--only: no view or probe named {', '.join(sorted(only - names))}")
    t_start = time.perf_counter()
    variant = init_mitsuba()
    log(f"mitsuba {mi.__version__}, variant {variant}, seed {seed}, out {out}")
    for sub in ("photos", "truth", "sparse/0", "probes") + (("extra",) if SHADE else ()):
        (out / sub).mkdir(parents=True, exist_ok=True)

    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    tex = make_textures(rng)
    renderer = Renderer(tex, seed)
    timings: dict[str, float] = {"textures_and_scene_s": time.perf_counter() - t0}
    log(f"textures + scene: {timings['textures_and_scene_s']:.1f} s")

    cams = camera_rig()
    fx, fy, cx, cy = intrinsics()
    views = []
    t0 = time.perf_counter()
    for i, cam in enumerate(cams):
        name = f"view_{i:02d}"
        if only is not None and name not in only:
            continue
        ti = time.perf_counter()
        radiance = renderer.pinhole(cam, i, SPP)
        exposure = exif_roundtrip(auto_exposure(radiance), out)
        note = (
            f"ground truth for photos/{name}.jpg; photo linear = radiance * ExposureTime "
            f"* K with ExposureTime={exposure!r} s, K={K_EXPOSURE}"
        )
        attrs = exr_attrs(note) | {
            "gaslight:view": f"{name}.jpg",
            "gaslight:ExposureTime": exposure,
        }
        write_image(out / "truth" / f"{name}.exr", radiance, attrs, oiio.HALF)
        write_image(
            out / "photos" / f"{name}.jpg",
            photo_pixels(radiance, exposure),
            {
                "ExposureTime": exposure,
                "FNumber": FNUMBER,
                "Exif:ISOSpeedRatings": ISO,
                "Exif:FocalLength": fx * SENSOR_WIDTH_MM / WIDTH,
                "Make": "gaslight2usd",
                "Model": "make_room.py pinhole",
                "oiio:ColorSpace": "srgb_rec709_scene",
                "Compression": f"jpeg:{JPEG_QUALITY}",
            },
            oiio.UINT8,
        )
        views.append(
            {
                "name": f"{name}.jpg",
                "truth": f"truth/{name}.exr",
                "exposure_time": exposure,
                "exposure_stops": round(math.log2(exposure) * 3) / 3,
                "centre": cam.centre.tolist(),
                "qvec": rot_to_quat(cam.w2c).tolist(),
                "tvec": cam.t.tolist(),
                "median_luminance": float(np.median(radiance @ LUMA)),
                "clipped_fraction": float(
                    np.mean((radiance * exposure * K_EXPOSURE).max(-1) >= 1.0)
                ),
            }
        )
        log(f"  {name}: {time.perf_counter() - ti:.1f} s, ExposureTime {exposure:.6g} s")
    timings["views_s"] = time.perf_counter() - t0
    extra_views = []
    for j, cam in enumerate(below_cameras() if SHADE is not None else []):
        name = f"below_{j:02d}"
        if only is not None and name not in only:
            continue
        radiance = renderer.pinhole(cam, len(cams) + j, SPP)
        write_image(out / "extra" / f"{name}.exr", radiance,
                    exr_attrs("true radiance of a frame from below the shaded lamp (no "
                              "photo: a darker frame is made from it)"), oiio.HALF)
        extra_views.append({"name": f"{name}.jpg", "truth": f"extra/{name}.exr",
                            "aimed_at": "lamp", "centre": cam.centre.tolist(),
                            "qvec": rot_to_quat(cam.w2c).tolist(), "tvec": cam.t.tolist()})
        log(f"  {name}: a frame from below the shade")

    t0 = time.perf_counter()
    probes = []
    for k, pos in enumerate(PROBE_POSITIONS):
        if only is not None and f"probe_{k}" not in only:
            continue
        ti = time.perf_counter()
        pano = renderer.latlong(pos, k, PROBE_SPP)
        attrs = exr_attrs(f"lat-long radiance probe at {pos.tolist()} (metres, +Y up)") | {
            "textureformat": "LatLong Environment",
            "gaslight:view": f"probe_{k}",
            "gaslight:position": ("float[3]", tuple(pos.tolist())),
        }
        write_image(out / "probes" / f"probe_{k}.exr", pano, attrs, oiio.HALF)
        probes.append({"name": f"probe_{k}.exr", "position": pos.tolist()})
        log(f"  probe_{k}: {time.perf_counter() - ti:.1f} s")
    timings["probes_s"] = time.perf_counter() - t0

    latlong_doc = (
        "OpenEXR envmap=latlong: column x, row y -> lon = -2*pi*((x+0.5)/W - 0.5), "
        "lat = pi*(0.5 - (y+0.5)/H), dir = (sin(lon)cos(lat), sin(lat), "
        "cos(lon)cos(lat)); centre column = +Z, column W/4 = +X, top row = +Y"
    )
    if only is None:  # a partial run's list would be short
        write_text(
            out / "probes" / "probes.json",
            json.dumps(
                {
                    "convention": latlong_doc,
                    "width": PROBE_W,
                    "height": PROBE_H,
                    "units": "metres, world frame of scene.json",
                    "probes": probes,
                },
                indent=2,
            )
            + "\n",
        )
    write_colmap(out / "sparse" / "0", cams)
    if only is not None:
        count = write_digests(out)
        log(f"done in {time.perf_counter() - t_start:.1f} s ({count} files, partial)")
        return

    medians = np.array([v["median_luminance"] for v in views])
    scene = {
        "name": "room",
        "generator": "examples/make_room.py",
        "seed": seed,
        "world_frame": {
            "up": "+Y",
            "units": "metres",
            "handedness": "right-handed",
            "origin": "room centre at floor height (floor is y = 0)",
        },
        "room": {
            "min": ROOM_MIN.tolist(),
            "max": ROOM_MAX.tolist(),
            "contact_gap_m": GAP,
            "note": "no two shapes touch: objects float contact_gap_m above their supports",
        },
        "image": {
            "width": WIDTH,
            "height": HEIGHT,
            "photos": "photos/view_NN.jpg",
            "truth": "truth/view_NN.exr",
        },
        "camera": {
            "model": "PINHOLE",
            "fx": fx,
            "fy": fy,
            "cx": cx,
            "cy": cy,
            "hfov_deg": HFOV_DEG,
            "axes": "COLMAP: x right, y down, z forward; poses world-to-camera",
            "pixels": "pixel (i, j) covers [i, i+1) x [j, j+1); its centre is +0.5",
        },
        "exposure": {
            "K": K_EXPOSURE,
            "FNumber": FNUMBER,
            "ISO": ISO,
            "formula": "photo_linear = clip(radiance * ExposureTime * K, 0, 1); "
            "jpeg = round(255 * sRGB_OETF(photo_linear))",
            "auto_exposure": f"median luminance * t * K = {TARGET_MEDIAN}, t rounded to 1/3 "
            "stop (2**(n/3) s), then to what EXIF stores",
            "exif_names": "ExposureTime, FNumber, Exif:ISOSpeedRatings (read back by "
            "OpenImageIO as Exif:PhotographicSensitivity)",
            "jpeg_quality": JPEG_QUALITY,
            "sensor_width_mm_nominal": SENSOR_WIDTH_MM,
        },
        "colour": {
            "truth": "lin_rec709_scene (OCIO 'Linear Rec.709 (sRGB)'), absolute "
            "radiance, half-float EXR, zip",
            "photos": "sRGB piecewise OETF, 8-bit JPEG (srgb_rec709_scene)",
        },
        "views": views,
        "lamp": {
            "center": LAMP_CENTER.tolist(),
            "radius": LAMP_RADIUS,
            "radiance": LAMP_RADIANCE.tolist(),
            "kind": "sphere area emitter",
        },
        "window": {
            "corners": window_corners().tolist(),
            "center": WINDOW_CENTER.tolist(),
            "normal": [-1.0, 0.0, 0.0],
            "radiance": WINDOW_RADIANCE.tolist(),
            "kind": "one-sided rectangle area emitter",
        },
        "measured": {
            "median_view_luminance": float(np.median(medians)),
            "lamp_to_median_ratio": float(LAMP_RADIANCE @ LUMA / np.median(medians)),
            "window_to_median_ratio": float(WINDOW_RADIANCE @ LUMA / np.median(medians)),
        },
        "probes": {
            "file": "probes/probes.json",
            "positions": PROBE_POSITIONS.tolist(),
            "width": PROBE_W,
            "height": PROBE_H,
            "convention": latlong_doc,
        },
        "render": {
            "renderer": "mitsuba",
            "mitsuba_version": mi.__version__,
            "variant": variant,
            "integrator": "path",
            "max_depth": MAX_DEPTH,
            "spp": SPP,
            "probe_spp": PROBE_SPP,
            "pixel_filter": "box (uniform jitter inside the pixel)",
        },
        "timings_file": "render_log.json (not covered by digests.json)",
    }
    if VARIANT != "room":  # the example's scene.json stays as it was (digests)
        scene["variant"] = VARIANT
        scene["lights"] = light_list()
        if SUN is not None:
            scene["sun_patch"] = {
                "min_xz": list(SUN["min"]), "max_xz": list(SUN["max"]),
                "irradiance_over_pi": np.asarray(SUN["radiance"]).tolist(),
                "kind": "sunlit floor (a rectangle emitter on the floor, radiance = the "
                        "floor's albedo x irradiance_over_pi): a lit surface the photos "
                        "clip, not one of the lights",
            }
        if extra_views:
            scene["extra_views"] = extra_views
        if not LAMP_ON:
            scene.pop("lamp")
            scene["measured"].pop("lamp_to_median_ratio")
    write_text(out / "scene.json", json.dumps(scene, indent=2) + "\n")

    count = write_digests(out)
    timings["total_s"] = time.perf_counter() - t_start
    write_text(
        out / "render_log.json",
        json.dumps(
            {
                "timings": timings,
                "cpu_count": os.cpu_count(),
                "variant": variant,
                "python": sys.version.split()[0],
            },
            indent=2,
        )
        + "\n",
    )
    log(f"done in {timings['total_s']:.1f} s ({count} files)")


def write_digests(out: Path) -> int:
    """``digests.json``: the SHA-256 of every generated file under ``out``; their count."""
    files = sorted(p for p in out.rglob("*") if p.is_file() and _is_generated(out, p))
    digests = {p.relative_to(out).as_posix(): sha256(p) for p in files}
    write_text(out / "digests.json", json.dumps(digests, indent=2) + "\n")
    return len(digests)


def _is_generated(out: Path, p: Path) -> bool:
    rel = p.relative_to(out).as_posix()
    return (rel.split("/")[0] in ("photos", "truth", "sparse", "probes", "extra")
            or rel == "scene.json")


# --------------------------------------------------------------------------- verification


def read_exr(path: Path) -> tuple[np.ndarray, Any]:
    """Pixels (float32) and spec of an image."""
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise RuntimeError(f"{path}: cannot read: {oiio.geterror()}")
    spec = inp.spec()
    pixels = inp.read_image(oiio.FLOAT)
    inp.close()
    return pixels, spec


def read_colmap(folder: Path) -> tuple[np.ndarray, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """Parse a COLMAP text model: (fx, fy, cx, cy), {name: (R_w2c, t)}."""
    cam_line = [
        ln
        for ln in (folder / "cameras.txt").read_text().splitlines()
        if ln and not ln.startswith("#")
    ][0].split()
    assert cam_line[1] == "PINHOLE", cam_line
    params = np.array([float(v) for v in cam_line[4:8]])
    lines = [
        ln for ln in (folder / "images.txt").read_text().splitlines() if not ln.startswith("#")
    ]
    poses = {}
    for ln in lines[::2]:
        f = ln.split()
        q = np.array([float(v) for v in f[1:5]])
        t = np.array([float(v) for v in f[5:8]])
        poses[f[9]] = (quat_to_rot(q), t)
    return params, poses


def bright_centroid(
    img: np.ndarray, near: tuple[float, float], level: float, box: int = 25
) -> tuple[float, float, int] | None:
    """Centroid (continuous coords) of pixels brighter than ``level`` around ``near``."""
    h, w, _ = img.shape
    x0, y0 = int(near[0]) - box, int(near[1]) - box
    xs = np.arange(x0, x0 + 2 * box + 1)
    ys = np.arange(y0, y0 + 2 * box + 1)
    ys = ys[(ys >= 0) & (ys < h)]
    xw = np.mod(xs, w)  # lat-long images wrap horizontally
    patch = img[ys][:, xw] @ LUMA
    mask = patch > level
    if mask.sum() == 0:
        return None
    yy, xx = np.nonzero(mask)
    return float(xs[xx].mean() + 0.5), float(ys[yy].mean() + 0.5), int(mask.sum())


def verify(out: Path) -> bool:
    """Check poses, EXIF, exposure convention and probe orientation of a generated folder."""
    scene = json.loads((out / "scene.json").read_text())
    (fx, fy, cx, cy), poses = read_colmap(out / "sparse" / "0")
    # the variants' lamp may be shaded, absent or under a pixel wide in the probes: its
    # checks only report there
    bare_lamp = "lamp" in scene and "variant" not in scene
    lamp_info = scene.get("lamp", {"center": [0.0, -100.0, 0.0], "radiance": [1e9] * 3})
    lamp = np.array(lamp_info["center"])
    lamp_lum = float(np.array(lamp_info["radiance"]) @ LUMA)
    width, height = scene["image"]["width"], scene["image"]["height"]
    ok = True
    errors = []
    seen = 0
    for view in scene["views"]:
        name = view["name"]
        truth, _ = read_exr(out / view["truth"])
        r, t = poses[name]
        p = r @ lamp + t
        inp = oiio.ImageInput.open(str(out / "photos" / name))
        spec = inp.spec()
        photo = inp.read_image(oiio.UINT8)
        inp.close()
        exif_t = spec.getattribute("ExposureTime")
        iso = spec.getattribute("Exif:PhotographicSensitivity") or spec.getattribute(
            "Exif:ISOSpeedRatings"
        )
        if (
            exif_t != view["exposure_time"]
            or spec.getattribute("FNumber") != FNUMBER
            or (iso != ISO)
        ):
            ok = False
            log(f"  {name}: EXIF mismatch {exif_t} {spec.getattribute('FNumber')} {iso}")
        # exposure convention: the decoded photo matches clip(truth * t * K) where unclipped
        expected = truth * exif_t * K_EXPOSURE
        decoded = srgb_eotf(photo / 255.0)
        keep = (expected.max(-1) < 0.9) & (expected.min(-1) > 0.02)
        ratio = float(decoded[keep].mean() / expected[keep].mean())
        if abs(ratio - 1) > 0.02:
            ok = False
            log(f"  {name}: photo / (truth * t * K) = {ratio:.4f}, expected 1")
        if p[2] <= 0:
            continue
        u, v = fx * p[0] / p[2] + cx, fy * p[1] / p[2] + cy
        if not (0 <= u < width and 0 <= v < height):
            continue
        c = bright_centroid(truth, (u, v), 0.5 * lamp_lum)
        if c is None:
            log(f"  {name}: lamp projects to ({u:.1f}, {v:.1f}) but is hidden")
            continue
        seen += 1
        err = math.hypot(c[0] - u, c[1] - v)
        errors.append(err)
        clipped = photo[int(v) - 1 : int(v) + 2, int(u) - 1 : int(u) + 2].mean() > 245
        log(
            f"  {name}: lamp projected ({u:.2f}, {v:.2f}), bright centroid ({c[0]:.2f}, "
            f"{c[1]:.2f}), {c[2]} px, error {err:.2f} px, clipped in photo: {clipped}"
        )
        ok &= err < 1.5 and clipped
    log(f"lamp seen in {seen} views, max projection error {max(errors, default=0):.2f} px")
    ok &= seen >= 3 or not bare_lamp

    win_rad = np.array(scene["window"]["radiance"])
    for probe in json.loads((out / "probes" / "probes.json").read_text())["probes"]:
        pano, spec = read_exr(out / "probes" / probe["name"])
        h, w, _ = pano.shape
        pos = np.array(probe["position"])
        env = spec.getattribute("textureformat")
        x, y = dir_to_latlong(lamp - pos, w, h)
        c = bright_centroid(pano, (x, y), 0.5 * lamp_lum)
        err = math.inf if c is None else math.hypot(c[0] - x, c[1] - y)
        wx, wy = dir_to_latlong(np.array(scene["window"]["center"]) - pos, w, h)
        win = pano[int(wy), int(wx)]
        win_err = float(np.max(np.abs(win / win_rad - 1)))
        log(
            f"  {probe['name']}: {env}; lamp expected ({x:.2f}, {y:.2f}) found "
            f"{c and (round(c[0], 2), round(c[1], 2))}, error {err:.2f} px; window pixel "
            f"{win.round(3).tolist()} vs {win_rad.round(3).tolist()} (rel. error {win_err:.4f})"
        )
        ok &= (err < 1.5 or not bare_lamp) and win_err < 0.01 and env == "LatLong Environment"
    log("verify: OK" if ok else "verify: FAILED")
    return bool(ok)


def main(argv: list[str] | None = None) -> int:
    """Command line entry point."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    ap.add_argument(
        "--out",
        type=Path,
        default=Path(__file__).resolve().parent / "room",
        help="output folder (default: examples/room next to this script)",
    )
    ap.add_argument(
        "--verify", action="store_true", help="only check an existing output folder (no rendering)"
    )
    ap.add_argument("--variant", default="room", choices=list(VARIANTS),
                    help="which room (default room: the bundled example; the others are "
                    "smaller renders of other lights and albedos for the chain bench)")
    ap.add_argument("--only", metavar="NAMES",
                    help="render only these views and probes (comma-separated stems, e.g. "
                    "view_03,probe_1; below_00: the shaded room's frames from below) with "
                    "the poses, to check that they come out as "
                    "committed; no scene.json, no --verify")
    args = ap.parse_args(argv)
    apply_variant(args.variant)
    if args.variant != "room" and args.out == ap.get_default("out"):
        ap.error("--variant needs --out (examples/room is the bundled example)")
    if args.only:
        if args.verify:
            ap.error("--only renders a part of the room; --verify checks a whole one")
        generate(args.out, args.seed, {n.strip() for n in args.only.split(",") if n.strip()})
        return 0
    if not args.verify:
        generate(args.out, args.seed)
    return 0 if verify(args.out) else 1


if __name__ == "__main__":
    sys.exit(main())
