"""The splat scene: the central data type of fitting and export.

Parameters are held exactly as a 3DGS PLY stores them (the "raw" form that
optimisers use), so a PLY round trip is bit-exact:

- ``positions``     (N, 3) float32, world frame
- ``rotations``     (N, 4) float32 quaternions, w x y z (not necessarily unit)
- ``log_scales``    (N, 3) float32, natural log of the Gaussian's std-devs
- ``opacity_logits``(N,)   float32, logit of the opacity
- ``sh``            (N, K, 3) float32, K = (degree + 1)**2 SH coefficients per
  channel; colour = 0.5 + SH_C0 * sh[:, 0] + ... (3DGS convention: the +0.5
  offset lives outside the coefficients). Colours are linear HDR, unclamped.
- ``normals``       (N, 3) float32 or None (some tools write zeros there)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

SH_C0 = 0.28209479177387814
"""The degree-0 real spherical harmonic, 1 / (2 sqrt(pi))."""

MAX_SH_DEGREE = 3


def sh_coefficient_count(degree: int) -> int:
    return (degree + 1) ** 2


def sh_degree_from_count(count: int) -> int:
    degree = int(round(count**0.5)) - 1
    if degree < 0 or sh_coefficient_count(degree) != count or degree > MAX_SH_DEGREE:
        raise ValueError(f"{count} SH coefficients per channel is not degree 0..3")
    return degree


def rgb_to_sh_dc(rgb: np.ndarray) -> np.ndarray:
    """Linear colour -> DC coefficient, 3DGS convention (with the +0.5 offset)."""
    return ((np.asarray(rgb, dtype=np.float32) - 0.5) / SH_C0).astype(np.float32)


def sh_dc_to_rgb(dc: np.ndarray) -> np.ndarray:
    return (np.asarray(dc, dtype=np.float32) * SH_C0 + 0.5).astype(np.float32)


def _sigmoid(x: np.ndarray) -> np.ndarray:
    return (1.0 / (1.0 + np.exp(-x.astype(np.float64)))).astype(np.float32)


def logit(p: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    p = np.clip(np.asarray(p, dtype=np.float64), eps, 1.0 - eps)
    return np.log(p / (1.0 - p)).astype(np.float32)


@dataclass
class SplatScene:
    positions: np.ndarray
    rotations: np.ndarray
    log_scales: np.ndarray
    opacity_logits: np.ndarray
    sh: np.ndarray
    normals: np.ndarray | None = None
    metadata: dict[str, Any] = field(default_factory=dict)
    """colour_space, exposure_scale, meters_per_unit, up_axis, provenance..."""

    def __post_init__(self) -> None:
        n = self.positions.shape[0]
        expect = {
            "positions": (n, 3),
            "rotations": (n, 4),
            "log_scales": (n, 3),
            "opacity_logits": (n,),
        }
        for name, shape in expect.items():
            arr = getattr(self, name)
            if arr.shape != shape:
                raise ValueError(f"{name} has shape {arr.shape}, expected {shape}")
        if self.sh.ndim != 3 or self.sh.shape[0] != n or self.sh.shape[2] != 3:
            raise ValueError(f"sh has shape {self.sh.shape}, expected ({n}, K, 3)")
        sh_degree_from_count(self.sh.shape[1])
        if self.normals is not None and self.normals.shape != (n, 3):
            raise ValueError(f"normals has shape {self.normals.shape}, expected ({n}, 3)")

    @property
    def count(self) -> int:
        return int(self.positions.shape[0])

    @property
    def sh_degree(self) -> int:
        return sh_degree_from_count(self.sh.shape[1])

    @property
    def scales(self) -> np.ndarray:
        """Linear std-devs (what USD ParticleField stores)."""
        return np.exp(self.log_scales).astype(np.float32)

    @property
    def opacities(self) -> np.ndarray:
        """Opacities in [0, 1] (what USD ParticleField stores)."""
        return _sigmoid(self.opacity_logits)

    @property
    def unit_rotations(self) -> np.ndarray:
        norm = np.linalg.norm(self.rotations, axis=1, keepdims=True)
        return (self.rotations / np.maximum(norm, 1e-12)).astype(np.float32)

    @property
    def base_colours(self) -> np.ndarray:
        """View-independent linear colour (DC term only), clamped at 0."""
        return np.maximum(sh_dc_to_rgb(self.sh[:, 0]), 0.0)

    def subset(self, mask_or_index: np.ndarray) -> SplatScene:
        pick = np.asarray(mask_or_index)
        return SplatScene(
            positions=self.positions[pick],
            rotations=self.rotations[pick],
            log_scales=self.log_scales[pick],
            opacity_logits=self.opacity_logits[pick],
            sh=self.sh[pick],
            normals=None if self.normals is None else self.normals[pick],
            metadata=dict(self.metadata),
        )

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        if self.count == 0:
            zero = np.zeros(3, dtype=np.float32)
            return zero, zero
        return self.positions.min(axis=0), self.positions.max(axis=0)

    @classmethod
    def from_activated(
        cls,
        positions: np.ndarray,
        colours: np.ndarray,
        scales: np.ndarray,
        opacities: np.ndarray,
        rotations: np.ndarray | None = None,
        sh_degree: int = 0,
        metadata: dict[str, Any] | None = None,
    ) -> SplatScene:
        """Build from linear colours, linear scales and [0, 1] opacities."""
        positions = np.asarray(positions, dtype=np.float32)
        n = positions.shape[0]
        sh = np.zeros((n, sh_coefficient_count(sh_degree), 3), dtype=np.float32)
        sh[:, 0] = rgb_to_sh_dc(colours)
        if rotations is None:
            rotations = np.tile(np.array([1, 0, 0, 0], dtype=np.float32), (n, 1))
        scales = np.broadcast_to(np.asarray(scales, dtype=np.float32).reshape(n, -1), (n, 3))
        return cls(
            positions=positions,
            rotations=np.asarray(rotations, dtype=np.float32),
            log_scales=np.log(np.maximum(scales, 1e-12)).astype(np.float32),
            opacity_logits=logit(np.asarray(opacities).reshape(n)),
            sh=sh,
            metadata=dict(metadata or {}),
        )
