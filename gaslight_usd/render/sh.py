"""Real spherical harmonics, degree 0 to 3, in the 3DGS convention.

colour = 0.5 + sum_k sh[k] * Y_k(d), clamped at 0 only (HDR: no upper clamp),
with d the unit direction from the camera centre to the splat. The basis and
its constants are the standard real SH (Sloan, "Stupid Spherical Harmonics
Tricks", 2008) with the sign convention of the 3DGS reference code.
"""

from __future__ import annotations

import torch

C0 = 0.28209479177387814
C1 = 0.4886025119029199
C2 = (1.0925484305920792, -1.0925484305920792, 0.31539156525252005,
      -1.0925484305920792, 0.5462742152960396)
C3 = (-0.5900435899266435, 2.890611442640554, -0.4570457994644658,
      0.3731763325901154, -0.4570457994644658, 1.445305721320277,
      -0.5900435899266435)


def sh_basis(directions: torch.Tensor, degree: int) -> torch.Tensor:
    """Unit directions (N, 3) -> basis values (N, (degree + 1)**2)."""
    if not 0 <= degree <= 3:
        raise ValueError(f"SH degree {degree} is not 0..3")
    x, y, z = directions.unbind(-1)
    terms = [torch.full_like(x, C0)]
    if degree >= 1:
        terms += [-C1 * y, C1 * z, -C1 * x]
    if degree >= 2:
        xx, yy, zz = x * x, y * y, z * z
        terms += [C2[0] * x * y, C2[1] * y * z, C2[2] * (2 * zz - xx - yy),
                  C2[3] * x * z, C2[4] * (xx - yy)]
    if degree >= 3:
        terms += [C3[0] * y * (3 * xx - yy), C3[1] * x * y * z,
                  C3[2] * y * (4 * zz - xx - yy), C3[3] * z * (2 * zz - 3 * xx - 3 * yy),
                  C3[4] * x * (4 * zz - xx - yy), C3[5] * z * (xx - yy),
                  C3[6] * x * (xx - 3 * yy)]
    return torch.stack(terms, dim=-1)


def eval_sh(sh: torch.Tensor, directions: torch.Tensor, degree: int | None = None
            ) -> torch.Tensor:
    """Linear colour (N, 3) of SH coefficients ``sh`` (N, K, 3) seen along ``directions``.

    ``degree`` (default: all that ``sh`` holds) may be lower than the stored
    degree, e.g. while fitting raises it step by step. Clamped at 0, not above.
    """
    stored = int(round(sh.shape[1] ** 0.5)) - 1
    degree = stored if degree is None else min(int(degree), stored)
    k = (degree + 1) ** 2
    basis = sh_basis(directions, degree)
    colour = torch.einsum("nk,nkc->nc", basis, sh[:, :k]) + 0.5
    return colour.clamp_min(0.0)
