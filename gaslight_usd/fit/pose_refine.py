"""Optional pose refinement: small corrections to the training views' poses.

SfM poses are good to a fraction of a pixel on the features they matched, but
the splats are fitted to every pixel, so a residual misalignment blurs the fit.
Each training view gets a correction ``(w, d)`` (axis-angle, translation),
zero at the start and optimised with the splats:
``R' = exp([w]x) R``, ``t' = exp([w]x) t + d`` (a rotation and shift in the
camera's own frame). Held-out views keep their given poses, so the held-out
error still measures the scene in the frame the user gave.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from ..cameras import PinholeCamera


def skew(w: torch.Tensor) -> torch.Tensor:
    """(3,) -> (3, 3) cross-product matrix ``[w]x``."""
    zero = w.new_zeros(())
    return torch.stack([torch.stack([zero, -w[2], w[1]]),
                        torch.stack([w[2], zero, -w[0]]),
                        torch.stack([-w[1], w[0], zero])])


class PoseRefiner:
    """Per-view pose corrections, each with its own Adam state.

    One view is rendered per step, so only that view's correction gets a
    gradient; a shared Adam would keep moving every other view on momentum
    alone. Each view's moments are updated only on its own steps.
    """

    BETAS = (0.9, 0.999)
    EPS = 1e-12

    def __init__(self, cameras: list[PinholeCamera], lr_rotation: float,
                 lr_translation: float, device: str | torch.device = "cpu"):
        f = torch.float32
        self.R = [torch.as_tensor(c.R, dtype=f, device=device) for c in cameras]
        self.t = [torch.as_tensor(c.t, dtype=f, device=device) for c in cameras]
        self.params = torch.zeros(len(cameras), 6, device=device, requires_grad=True)
        """(views, 6): axis-angle rotation (radians), then translation"""
        self.lr = torch.tensor([lr_rotation] * 3 + [lr_translation] * 3, device=device)
        self.moment1 = torch.zeros(len(cameras), 6, device=device)
        self.moment2 = torch.zeros(len(cameras), 6, device=device)
        self.steps = torch.zeros(len(cameras), dtype=torch.long)

    @property
    def rotation(self) -> torch.Tensor:
        return self.params[:, :3]

    def pose(self, k: int) -> tuple[torch.Tensor, torch.Tensor]:
        """Corrected world-to-camera ``(R, t)`` of view ``k`` (differentiable)."""
        turn = torch.linalg.matrix_exp(skew(self.params[k, :3]))
        return turn @ self.R[k], turn @ self.t[k] + self.params[k, 3:]

    def step(self, k: int) -> None:
        """An Adam step of view ``k``'s correction from its gradient; clears the gradient."""
        grad = self.params.grad
        if grad is None:
            return
        b1, b2 = self.BETAS
        with torch.no_grad():
            g = grad[k]
            self.steps[k] += 1
            n = int(self.steps[k])
            self.moment1[k] = b1 * self.moment1[k] + (1 - b1) * g
            self.moment2[k] = b2 * self.moment2[k] + (1 - b2) * g * g
            m_hat = self.moment1[k] / (1 - b1 ** n)
            v_hat = self.moment2[k] / (1 - b2 ** n)
            self.params[k] -= self.lr * m_hat / (v_hat.sqrt() + self.EPS)
        self.params.grad = None

    def cameras(self, cameras: list[PinholeCamera]) -> list[PinholeCamera]:
        """``cameras`` (the same views, in order) with the corrected poses."""
        out = []
        with torch.no_grad():
            for k, cam in enumerate(cameras):
                R, t = self.pose(k)
                out.append(PinholeCamera(cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy,
                                         R.double().cpu().numpy(), t.double().cpu().numpy(),
                                         cam.name))
        return out

    def summary(self, cameras: list[PinholeCamera]) -> dict[str, float]:
        """How far the corrections moved the views: rotation (degrees) and centre shift."""
        with torch.no_grad():
            angles = np.degrees(self.rotation.norm(dim=1).cpu().numpy())
        before = np.array([c.center for c in cameras])
        after = np.array([c.center for c in self.cameras(cameras)])
        shift = np.linalg.norm(after - before, axis=1)
        return {"views": len(cameras),
                "rotation_deg_median": round(float(np.median(angles)), 4),
                "rotation_deg_max": round(float(angles.max()), 4),
                "centre_shift_median": round(float(np.median(shift)), 5),
                "centre_shift_max": round(float(shift.max()), 5)}

    def state_dict(self) -> dict:
        return {"params": self.params.detach().cpu().clone(),
                "moment1": self.moment1.cpu().clone(), "moment2": self.moment2.cpu().clone(),
                "steps": self.steps.clone()}

    def load_state_dict(self, state: dict) -> None:
        with torch.no_grad():
            self.params.copy_(state["params"])
        dev = self.params.device
        self.moment1, self.moment2 = state["moment1"].to(dev), state["moment2"].to(dev)
        self.steps = state["steps"].clone()


def rotation_error_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Angle (degrees) of the rotation taking ``b`` to ``a`` (both (3, 3))."""
    cos = (np.trace(a @ b.T) - 1.0) / 2.0
    return math.degrees(math.acos(float(np.clip(cos, -1.0, 1.0))))
