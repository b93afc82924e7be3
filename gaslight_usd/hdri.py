"""HDRI files: lat-long and cube-map EXRs (and tiled mip-mapped .tx) at probe points.

Conventions (also written into every EXR header as ``gaslight:convention``):

- lat-long as OpenEXR ``envmap=latlong``: image centre looks along +Z, a
  quarter width from the left edge along +X, the top row is +Y; width = 2 x
  height;
- cube as OpenEXR ``envmap=cube``: six square faces stacked vertically in the
  order +X, -X, +Y, -Y, +Z, -Z, face orientation as OpenEXR's ImfEnvmap;
  separate face files (``--faces``) hold the same six images;
- positions and directions are in the world frame of the splats (the poses the
  user gave, or the frame the project chose and recorded for SfM poses);
- radiance is scene-linear and unclamped (float EXR when a value exceeds the
  half range), in the chosen OCIO output space (default: the working space);
- ``.tx``: OpenImageIO ``make_texture`` with ``MakeTxEnvLatl`` (a tiled,
  mip-mapped lat-long environment; cube maps have no .tx form in OIIO).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import OpenImageIO as oiio

from . import colour
from .atomic import atomic_path
from .errors import GaslightError
from .export_options import HDRI_WIDTH
from .imageio import write_exr
from .provenance import tool_version

LATLONG_CONVENTION = ("OpenEXR envmap=latlong: centre +Z, quarter width +X, top row +Y; "
                      "world frame of the splats; scene-linear unclamped radiance")
CUBE_CONVENTION = ("OpenEXR envmap=cube: faces stacked vertically +X,-X,+Y,-Y,+Z,-Z; "
                   "world frame of the splats; scene-linear unclamped radiance")
FACE_NAMES = ("px", "nx", "py", "ny", "pz", "nz")


@dataclass
class ProbeFiles:
    position: tuple[float, float, float]
    latlong: Path | None = None
    cube: Path | None = None
    faces: list[Path] = field(default_factory=list)
    tx: Path | None = None

    def all(self) -> list[Path]:
        return [p for p in (self.latlong, self.cube, *self.faces, self.tx) if p is not None]


def probe_attributes(position: Sequence[float], convention: str,
                     extra: Mapping[str, Any] | None = None) -> dict[str, Any]:
    attrs: dict[str, Any] = {
        "gaslight:convention": convention,
        "gaslight:probePosition": [float(v) for v in position],
        "gaslight:radiance": "scene-linear, unclamped",
        "Software": f"gaslight2usd {tool_version()}",
    }
    attrs.update(extra or {})
    return attrs


def _to_output(pixels: np.ndarray, working_space: str, output_space: str | None,
               config_uri: str | None) -> tuple[np.ndarray, str]:
    dst = output_space or working_space
    return colour.convert(pixels, working_space, dst, config_uri), dst


def write_latlong(path: str | Path, pixels: np.ndarray, position: Sequence[float],
                  working_space: str = colour.DEFAULT_WORKING_SPACE,
                  output_space: str | None = None, config_uri: str | None = None,
                  attributes: Mapping[str, Any] | None = None) -> Path:
    """Write an (H, 2H, 3) working-space panorama as a lat-long EXR."""
    pixels = np.asarray(pixels, np.float32)
    if pixels.ndim != 3 or pixels.shape[1] != 2 * pixels.shape[0]:
        raise ValueError(f"lat-long pixels must be (H, 2H, 3), got {pixels.shape}")
    data, space = _to_output(pixels, working_space, output_space, config_uri)
    attrs = probe_attributes(position, LATLONG_CONVENTION, attributes)
    attrs["textureformat"] = "LatLong Environment"  # OIIO writes envmap=latlong
    return write_exr(path, data, space, attrs, config_uri=config_uri)


def write_cube(path: str | Path, faces: np.ndarray, position: Sequence[float],
               working_space: str = colour.DEFAULT_WORKING_SPACE,
               output_space: str | None = None, config_uri: str | None = None,
               attributes: Mapping[str, Any] | None = None) -> Path:
    """Write (6, S, S, 3) faces as one OpenEXR cube map (6S x S, envmap=cube)."""
    faces = np.asarray(faces, np.float32)
    if faces.ndim != 4 or faces.shape[0] != 6 or faces.shape[1] != faces.shape[2]:
        raise ValueError(f"cube faces must be (6, S, S, 3), got {faces.shape}")
    data, space = _to_output(faces.reshape(-1, *faces.shape[2:]), working_space,
                             output_space, config_uri)
    attrs = probe_attributes(position, CUBE_CONVENTION, attributes)
    attrs["textureformat"] = "CubeFace Environment"  # OIIO writes envmap=cube
    return write_exr(path, data, space, attrs, config_uri=config_uri)


def face_paths(path: str | Path) -> list[Path]:
    """``probe.exr`` -> ``probe.px.exr``, ``probe.nx.exr``... (+X, -X, +Y, -Y, +Z, -Z)."""
    path = Path(path)
    return [path.with_name(f"{path.stem}.{name}{path.suffix}") for name in FACE_NAMES]


def write_faces(path: str | Path, faces: np.ndarray, position: Sequence[float],
                working_space: str = colour.DEFAULT_WORKING_SPACE,
                output_space: str | None = None, config_uri: str | None = None,
                attributes: Mapping[str, Any] | None = None) -> list[Path]:
    """Each cube face as its own EXR (same orientation as inside the cube map)."""
    written = []
    for i, (face_path, label) in enumerate(zip(face_paths(path),
                                               ("+X", "-X", "+Y", "-Y", "+Z", "-Z"),
                                               strict=True)):
        data, space = _to_output(faces[i], working_space, output_space, config_uri)
        attrs = probe_attributes(position, CUBE_CONVENTION, attributes)
        attrs["gaslight:cubeFace"] = label
        written.append(write_exr(face_path, data, space, attrs, config_uri=config_uri))
    return written


def write_tx(latlong_exr: str | Path, tx_path: str | Path) -> Path:
    """Tiled, mip-mapped lat-long environment texture via OpenImageIO's maketx."""
    tx_path = Path(tx_path)
    config = oiio.ImageSpec()
    config.attribute("maketx:highlightcomp", 0)
    with atomic_path(tx_path) as tmp:
        ok = oiio.ImageBufAlgo.make_texture(oiio.MakeTxEnvLatl, str(latlong_exr), str(tmp),
                                            config)
        if not ok:
            raise GaslightError(f"maketx failed: {oiio.geterror()}", tx_path)
    return tx_path


def probe_output_paths(output: str | Path, count: int) -> list[Path]:
    """One EXR name per probe: ``probe.exr`` or ``probe.000.exr``, ``probe.001.exr``...

    ``output`` may also be a folder (no suffix): ``<folder>/probe_NNN.exr``.
    """
    output = Path(output)
    if output.suffix.lower() != ".exr":
        return [output / f"probe_{i:03d}.exr" for i in range(count)]
    if count == 1:
        return [output]
    return [output.with_name(f"{output.stem}.{i:03d}.exr") for i in range(count)]


def render_probe(scene, position: Sequence[float], path: str | Path,
                 width: int = HDRI_WIDTH, cube: bool = False, faces: bool = False,
                 tx: bool = False, working_space: str = colour.DEFAULT_WORKING_SPACE,
                 output_space: str | None = None, config_uri: str | None = None,
                 attributes: Mapping[str, Any] | None = None,
                 device: str = "cpu") -> ProbeFiles:
    """Render the splats at ``position`` and write the requested HDRI files.

    ``width`` is the lat-long width (height = width // 2); cube faces are
    ``width // 4`` pixels square (a 90 degree face at the lat-long's
    resolution).
    """
    from .render.envmap import render_cube, render_latlong

    if width < 8 or width % 2:
        raise ValueError(f"lat-long width must be an even number >= 8, got {width}")
    path = Path(path)
    pos = tuple(float(v) for v in position)
    files = ProbeFiles(position=pos)
    pano = render_latlong(scene, pos, width, device=device)
    files.latlong = write_latlong(path, pano, pos, working_space, output_space, config_uri,
                                  attributes)
    if cube or faces:
        face_size = max(width // 4, 2)
        cube_faces = render_cube(scene, pos, face_size, device=device)
        if cube:
            files.cube = write_cube(path.with_name(f"{path.stem}.cube{path.suffix}"),
                                    cube_faces, pos, working_space, output_space,
                                    config_uri, attributes)
        if faces:
            files.faces = write_faces(path, cube_faces, pos, working_space, output_space,
                                      config_uri, attributes)
    if tx:
        files.tx = write_tx(files.latlong, path.with_suffix(".tx"))
    return files
