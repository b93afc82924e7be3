"""Native splats: ``UsdVol.ParticleField3DGaussianSplat`` from whole arrays.

Layout written (usd-core 26.11 schema):

- ``positions`` point3f[], ``orientations`` quatf[] (unit; Gf.Quatf stores
  x y z w in memory, so our w x y z rows are rolled), ``scales`` float3[]
  (linear std-devs), ``opacities`` float[] in [0, 1];
- ``radiance:sphericalHarmonicsDegree`` and
  ``radiance:sphericalHarmonicsCoefficients`` float3[]: (degree+1)^2 RGB
  triples per particle, contiguous per particle, DC first then the PLY's
  f_rest order (l = 1..3, m = -l..l), 3DGS convention with the +0.5 offset
  outside the coefficients (as the schema's fallback DC of 0.5 implies);
- ``--half``: the ``...h`` twins instead (positions stay float: half
  precision positions lose millimetres a few metres from the origin);
- ``extent`` from the positions padded by 3 std-devs; ``primvars:displayColor``
  the linear base colour (for viewers that draw points).

Every array goes through ``Vt.*Array.FromNumpy``: no Python loop per splat.
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd, UsdGeom, UsdVol, Vt

from ..splats import SplatScene

MAX_LAYER_BYTES = 3 * 2**30
"""Split the splats over several layers above this (USDZ has no ZIP64: 4 GiB)."""


def bytes_per_splat(sh_count: int, half: bool = False) -> int:
    """Payload bytes one splat takes in a .usdc (uncompressed arrays)."""
    scalar = 2 if half else 4
    return 12 + 4 * scalar + 3 * scalar + scalar + 3 * scalar * sh_count + 12


def chunk_ranges(count: int, per_splat: int, max_bytes: int = MAX_LAYER_BYTES
                 ) -> list[tuple[int, int]]:
    """Contiguous (start, stop) ranges whose payload stays under ``max_bytes``."""
    per_chunk = max(1, int(max_bytes) // max(per_splat, 1))
    if count == 0:
        return [(0, 0)]
    return [(s, min(s + per_chunk, count)) for s in range(0, count, per_chunk)]


def splat_extent(scene: SplatScene, scales: np.ndarray | None = None) -> np.ndarray:
    """(2, 3) box around the positions padded by 3 std-devs of each splat."""
    if scene.count == 0:
        return np.zeros((2, 3), np.float32)
    scales = scene.scales if scales is None else scales
    pad = 3.0 * scales.max(axis=1, keepdims=True)
    lo = (scene.positions - pad).min(axis=0)
    hi = (scene.positions + pad).max(axis=0)
    return np.stack([lo, hi]).astype(np.float32)


def _xyzw(rotations_wxyz: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(rotations_wxyz, axis=1, keepdims=True)
    unit = rotations_wxyz / np.maximum(norm, 1e-12)
    return np.ascontiguousarray(np.roll(unit, -1, axis=1), dtype=np.float32)


def write_particle_field(stage: Usd.Stage, path: str | Sdf.Path, scene: SplatScene,
                         half: bool = False) -> UsdVol.ParticleField3DGaussianSplat:
    """Define a ParticleField3DGaussianSplat at ``path`` holding ``scene``."""
    field = UsdVol.ParticleField3DGaussianSplat.Define(stage, Sdf.Path(str(path)))
    n = scene.count
    field.CreatePositionsAttr(Vt.Vec3fArray.FromNumpy(
        np.ascontiguousarray(scene.positions, np.float32)))
    orient = _xyzw(scene.rotations)
    scales = np.ascontiguousarray(scene.scales, np.float32)
    opacities = np.ascontiguousarray(scene.opacities, np.float32)
    coeffs = np.ascontiguousarray(scene.sh.reshape(n * scene.sh.shape[1], 3), np.float32)
    if half:
        field.CreateOrientationshAttr(Vt.QuathArray.FromNumpy(orient.astype(np.float16)))
        field.CreateScaleshAttr(Vt.Vec3hArray.FromNumpy(scales.astype(np.float16)))
        field.CreateOpacitieshAttr(Vt.HalfArray.FromNumpy(opacities.astype(np.float16)))
        field.CreateRadianceSphericalHarmonicsCoefficientshAttr(
            Vt.Vec3hArray.FromNumpy(coeffs.astype(np.float16)))
    else:
        field.CreateOrientationsAttr(Vt.QuatfArray.FromNumpy(orient))
        field.CreateScalesAttr(Vt.Vec3fArray.FromNumpy(scales))
        field.CreateOpacitiesAttr(Vt.FloatArray.FromNumpy(opacities))
        field.CreateRadianceSphericalHarmonicsCoefficientsAttr(Vt.Vec3fArray.FromNumpy(coeffs))
    field.CreateRadianceSphericalHarmonicsDegreeAttr(int(scene.sh_degree))
    field.CreateExtentAttr(Vt.Vec3fArray.FromNumpy(splat_extent(scene, scales)))
    field.CreateProjectionModeHintAttr(UsdVol.Tokens.perspective)
    field.CreateSortingModeHintAttr(UsdVol.Tokens.zDepth)
    display = UsdGeom.PrimvarsAPI(field.GetPrim()).CreatePrimvar(
        "displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.vertex)
    display.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(scene.base_colours, np.float32)))
    return field


def read_particle_field(prim: Usd.Prim) -> dict[str, np.ndarray]:
    """Arrays of a ParticleField3DGaussianSplat (float or half twins), as numpy.

    ``orientations`` come back as w x y z rows; ``sh`` as (N, K, 3).
    """
    field = UsdVol.ParticleField3DGaussianSplat(prim)

    def get(full, halfa) -> np.ndarray | None:
        for attr in (full, halfa):
            value = attr.Get() if attr and attr.HasAuthoredValue() else None
            if value is not None:
                return np.asarray(value, dtype=np.float32)
        return None

    positions = get(field.GetPositionsAttr(), field.GetPositionshAttr())
    n = 0 if positions is None else len(positions)
    orient = get(field.GetOrientationsAttr(), field.GetOrientationshAttr())
    coeffs = get(field.GetRadianceSphericalHarmonicsCoefficientsAttr(),
                 field.GetRadianceSphericalHarmonicsCoefficientshAttr())
    degree = field.GetRadianceSphericalHarmonicsDegreeAttr().Get()
    k = (degree + 1) ** 2
    return {
        "positions": positions,
        "orientations": None if orient is None else np.roll(orient, 1, axis=1),
        "scales": get(field.GetScalesAttr(), field.GetScaleshAttr()),
        "opacities": get(field.GetOpacitiesAttr(), field.GetOpacitieshAttr()),
        "sh": None if coeffs is None else coeffs.reshape(n, k, 3),
        "extent": np.asarray(field.GetExtentAttr().Get(), np.float32),
    }
