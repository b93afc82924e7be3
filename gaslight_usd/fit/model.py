"""The optimised splat model: leaf tensors, their Adam optimiser, densify and prune.

Colour is optimised as log radiance plus SH terms relative to it, so one
learning rate suits a dim wall and a lamp 1000x brighter alike (an additive
step on a colour of 500 would take forever). It converts exactly to the 3DGS
convention: DC = (exp(g) - 0.5) / C0, higher terms = exp(g) * relative terms,
so colour = exp(g) (1 + sum rel Y), clamped at 0 by the renderer.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from ..render import SplatParams
from ..render.project import quat_to_rotmat
from ..render.sh import C0
from ..splats import SplatScene

NAMES = ("means", "quats", "log_scales", "opacity_logits", "log_colour", "sh_rel")
MAX_DEGREE = 3


class SplatModel:
    antialiased: bool = False
    """Render in the antialiased mode (:func:`~gaslight_usd.render.project.project`)."""

    def __init__(self, tensors: dict[str, torch.Tensor], lrs: dict[str, float]):
        self.t = {k: tensors[k].detach().clone().requires_grad_(True) for k in NAMES}
        self.lrs = dict(lrs)
        # fused: one kernel per tensor and step (the default's chain of per-tensor ops
        # took a seventh of a fit's training steps on CPU; profile ``gaslight2usd run``)
        self.opt = torch.optim.Adam(
            [{"params": [self.t[k]], "lr": lrs[k], "name": k} for k in NAMES], eps=1e-15,
            fused=True)

    @property
    def count(self) -> int:
        return int(self.t["means"].shape[0])

    @classmethod
    def initial(cls, positions: np.ndarray, colours: np.ndarray, scales: np.ndarray,
                opacity: float, lrs: dict[str, float], device: str | torch.device = "cpu"
                ) -> SplatModel:
        n = len(positions)
        f = torch.float32
        tensors = {
            "means": torch.as_tensor(positions, dtype=f),
            "quats": torch.tensor([1.0, 0, 0, 0]).repeat(n, 1),
            "log_scales": torch.log(torch.as_tensor(scales, dtype=f).clamp_min(1e-7))
            .reshape(n, 1).repeat(1, 3),
            "opacity_logits": torch.full((n,), math.log(opacity / (1 - opacity))),
            "log_colour": torch.log(torch.as_tensor(colours, dtype=f).clamp_min(1e-4)),
            "sh_rel": torch.zeros(n, (MAX_DEGREE + 1) ** 2 - 1, 3),
        }
        return cls({k: v.to(device) for k, v in tensors.items()}, lrs)

    def params(self, degree: int = MAX_DEGREE) -> SplatParams:
        """Differentiable SplatParams (3DGS convention) at SH ``degree``."""
        base = torch.exp(self.t["log_colour"])
        k = (degree + 1) ** 2 - 1
        return SplatParams(means=self.t["means"], quats=self.t["quats"],
                           log_scales=self.t["log_scales"],
                           opacity_logits=self.t["opacity_logits"],
                           sh_dc=(base - 0.5) / C0,
                           sh_rest=base[:, None, :] * self.t["sh_rel"][:, :k],
                           antialiased=self.antialiased)

    def to_scene(self, degree: int, metadata: dict) -> SplatScene:
        with torch.no_grad():
            return self.params(degree).detach().to_scene(metadata)

    def step(self) -> None:
        self.opt.step()
        self.opt.zero_grad(set_to_none=True)

    def set_lr(self, name: str, lr: float) -> None:
        for group in self.opt.param_groups:
            if group["name"] == name:
                group["lr"] = lr

    # -- changing the splat set, keeping Adam's moments --------------------------
    def _replace(self, keep: torch.Tensor, extra: dict[str, torch.Tensor] | None) -> None:
        for group in self.opt.param_groups:
            name = group["name"]
            old = group["params"][0]
            state = self.opt.state.pop(old, None)
            new = old.detach()[keep]
            if extra is not None:
                new = torch.cat([new, extra[name].detach()])
            new = new.clone().requires_grad_(True)
            if state:
                for key in ("exp_avg", "exp_avg_sq"):
                    moment = state[key][keep]
                    if extra is not None:
                        moment = torch.cat([moment, torch.zeros_like(extra[name])])
                    state[key] = moment
                self.opt.state[new] = state
            group["params"][0] = new
            self.t[name] = new

    def set_rows(self, rows: torch.Tensor, values: dict[str, torch.Tensor]) -> None:
        """Overwrite ``rows`` of the named tensors in place (a splat moved by a rule, not
        by a gradient), their Adam moments cleared so no old momentum drags them back."""
        for group in self.opt.param_groups:
            name = group["name"]
            if name not in values:
                continue
            leaf = group["params"][0]
            with torch.no_grad():
                leaf[rows] = values[name].to(leaf.dtype)
            state = self.opt.state.get(leaf)
            if state:
                for key in ("exp_avg", "exp_avg_sq"):
                    state[key][rows] = 0.0

    def prune(self, remove: torch.Tensor) -> None:
        self._replace(~remove, None)

    def add(self, positions: np.ndarray, colours: np.ndarray, scales: np.ndarray,
            opacity: float) -> None:
        """Append isotropic splats (as :meth:`initial` makes them), fresh Adam moments."""
        if not len(positions):
            return
        device = self.t["means"].device
        new = SplatModel.initial(positions, colours, scales, opacity, self.lrs, device)
        keep = torch.ones(self.count, dtype=torch.bool, device=device)
        self._replace(keep, {k: v.detach() for k, v in new.t.items()})

    def densify(self, clone: torch.Tensor, split: torch.Tensor, generator: torch.Generator
                ) -> None:
        """3DGS densification: copy small splats, split big ones into two smaller."""
        t = {k: v.detach() for k, v in self.t.items()}
        cloned = {k: v[clone] for k, v in t.items()}
        s = torch.exp(t["log_scales"][split])
        rot = quat_to_rotmat(t["quats"][split])
        samples = []
        for _ in range(2):
            # drawn on the CPU whatever the device: the same splits on CPU and GPU
            noise = torch.randn(s.shape, generator=generator).to(s.device) * s
            samples.append(t["means"][split] + (rot @ noise[..., None])[..., 0])
        halves = {k: v[split].repeat(2, *([1] * (v.dim() - 1))) for k, v in t.items()}
        halves["means"] = torch.cat(samples)
        halves["log_scales"] = halves["log_scales"] - math.log(1.6)
        extra = {k: torch.cat([cloned[k], halves[k]]) for k in NAMES}
        self._replace(~split, extra)

    def state_dict(self) -> dict:
        return {"tensors": {k: v.detach().clone() for k, v in self.t.items()},
                "optimizer": self.opt.state_dict(), "lrs": self.lrs}

    @classmethod
    def from_state(cls, state: dict, device: str | torch.device = "cpu") -> SplatModel:
        model = cls({k: v.to(device) for k, v in state["tensors"].items()}, state["lrs"])
        model.opt.load_state_dict(state["optimizer"])
        return model
