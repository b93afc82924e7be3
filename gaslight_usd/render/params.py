"""SplatParams: the splat scene as torch tensors, the form the renderer and the
optimiser work on. Raw (pre-activation) values, exactly as SplatScene/PLY hold
them, so a round trip is lossless.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from ..splats import SplatScene

FIELDS = ("means", "quats", "log_scales", "opacity_logits", "sh_dc", "sh_rest")


@dataclass
class SplatParams:
    """Splat parameters as tensors (N splats, K = (degree + 1)**2 SH coefficients).

    - ``means``          (N, 3) world positions
    - ``quats``          (N, 4) rotations w x y z (normalised when used)
    - ``log_scales``     (N, 3) natural log of the std-devs
    - ``opacity_logits`` (N,)   logit of the opacity
    - ``sh_dc``          (N, 3) DC SH coefficient (3DGS +0.5 convention)
    - ``sh_rest``        (N, K - 1, 3) higher-order SH coefficients

    ``antialiased``: how the renderer draws them (see :func:`.project.project`);
    a scene carries it as ``metadata["antialiased"]`` (the fit sets it).
    """

    means: torch.Tensor
    quats: torch.Tensor
    log_scales: torch.Tensor
    opacity_logits: torch.Tensor
    sh_dc: torch.Tensor
    sh_rest: torch.Tensor
    antialiased: bool = False

    @property
    def count(self) -> int:
        return int(self.means.shape[0])

    @property
    def sh(self) -> torch.Tensor:
        """(N, K, 3) all SH coefficients."""
        return torch.cat([self.sh_dc[:, None], self.sh_rest], dim=1)

    @property
    def sh_degree(self) -> int:
        return int(round((self.sh_rest.shape[1] + 1) ** 0.5)) - 1

    def tensors(self) -> dict[str, torch.Tensor]:
        return {name: getattr(self, name) for name in FIELDS}

    def to(self, device: str | torch.device) -> SplatParams:
        return SplatParams(**{k: v.to(device) for k, v in self.tensors().items()},
                           antialiased=self.antialiased)

    def detach(self) -> SplatParams:
        return SplatParams(**{k: v.detach() for k, v in self.tensors().items()},
                           antialiased=self.antialiased)

    @classmethod
    def from_scene(cls, scene: SplatScene, device: str | torch.device = "cpu",
                   requires_grad: bool = False) -> SplatParams:
        def t(a: np.ndarray) -> torch.Tensor:
            out = torch.as_tensor(np.ascontiguousarray(a, dtype=np.float32), device=device)
            return out.clone().requires_grad_(requires_grad)

        return cls(means=t(scene.positions), quats=t(scene.rotations),
                   log_scales=t(scene.log_scales), opacity_logits=t(scene.opacity_logits),
                   sh_dc=t(scene.sh[:, 0]), sh_rest=t(scene.sh[:, 1:]),
                   antialiased=is_antialiased(scene))

    def to_scene(self, metadata: dict[str, Any] | None = None) -> SplatScene:
        def a(x: torch.Tensor) -> np.ndarray:
            return x.detach().cpu().numpy().astype(np.float32)

        meta = dict(metadata or {})
        if self.antialiased:
            meta["antialiased"] = True
        return SplatScene(positions=a(self.means), rotations=a(self.quats),
                          log_scales=a(self.log_scales), opacity_logits=a(self.opacity_logits),
                          sh=a(self.sh), metadata=meta)


def is_antialiased(scene: SplatScene) -> bool:
    """Whether ``scene`` was fitted to be drawn in the antialiased mode (its metadata)."""
    return scene.metadata.get("antialiased") in (True, 1, "1", "true", "True")
