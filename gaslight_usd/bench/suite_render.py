"""Bench suite "render": the splat renderer's speed.

Milliseconds per 256x256 forward pass and per backward pass (gradients of all
splat parameters, SH degree 3) for 10k, 50k and 200k random splats in front of
the camera (scales shrink with the count so the image stays similarly
covered), for both compositing back ends on the CPU (``numba``: the compiled
kernels, the CPU default; ``torch``: vectorised torch) and, where torch sees a
GPU, the torch back end on CUDA; tile sizes 8 and 16, with ``speedup`` = the
torch CPU time / the row's time at the same count and tile. The times include the
projection and SH (torch in both). Median of 3 timed runs after one warm-up
(which also loads or compiles the kernels); wall time on this machine with its
thread count, so compare rows of one run only. Quick mode: 10k splats, 2 runs.
"""

from __future__ import annotations

import os
import time
from typing import Any

import numpy as np
import torch

from ..cameras import PinholeCamera
from ..render import RASTERIZER_ENV, SplatParams, render
from ..splats import SplatScene

NAME = "render"
DESCRIPTION = "splat renderer: ms per 256x256 forward + backward pass vs splat count"
X = ("splats", "splats")
Y = ("ms_forward_backward", "ms per 256x256 forward + backward pass")
HIGHER_IS_BETTER = False
TABLE = ("splats", "tile", "ms_forward", "ms_backward", "ms_forward_backward", "speedup",
         "mean_alpha")
BACKENDS = (("numba", "cpu"), ("torch", "cpu"), ("torch", "cuda"))
"""Compositing back end and device; the CUDA rows only where torch sees a GPU."""
SIZE = 256


def random_scene(n: int, rng: np.random.Generator) -> SplatScene:
    pos = rng.uniform([-1.5, -1.5, 2.0], [1.5, 1.5, 6.0], (n, 3))
    scales = np.exp(rng.uniform(np.log(0.005), np.log(0.05), (n, 3))) * (1e4 / n) ** (1 / 3)
    scene = SplatScene.from_activated(pos, rng.uniform(0, 3, (n, 3)), scales,
                                      rng.uniform(0.05, 0.99, n),
                                      rotations=rng.normal(size=(n, 4)), sh_degree=3)
    scene.sh[:, 1:] = rng.normal(0, 0.1, scene.sh[:, 1:].shape)
    return scene


def time_render(scene: SplatScene, cam: PinholeCamera, tile: int, runs: int,
                backend: str, device: str = "cpu") -> tuple[float, float, float]:
    previous = os.environ.get(RASTERIZER_ENV)
    os.environ[RASTERIZER_ENV] = backend
    try:
        return _time_render(scene, cam, tile, runs, torch.device(device))
    finally:
        if previous is None:
            os.environ.pop(RASTERIZER_ENV, None)
        else:
            os.environ[RASTERIZER_ENV] = previous


def _time_render(scene: SplatScene, cam: PinholeCamera, tile: int, runs: int,
                 device: torch.device) -> tuple[float, float, float]:
    params = SplatParams.from_scene(scene, device=device, requires_grad=True)

    def sync() -> None:  # GPU work is asynchronous: time it when it has finished
        if device.type == "cuda":
            torch.cuda.synchronize(device)

    fwd, bwd = [], []
    for i in range(runs + 1):
        sync()
        t0 = time.perf_counter()
        out = render(params, cam, tile=tile)
        sync()
        t1 = time.perf_counter()
        out.image.sum().backward()
        sync()
        t2 = time.perf_counter()
        for v in params.tensors().values():
            v.grad = None
        if i:  # the first run warms up
            fwd.append(t1 - t0)
            bwd.append(t2 - t1)
    cover = float(out.alpha.detach().mean())
    return float(np.median(fwd)) * 1e3, float(np.median(bwd)) * 1e3, cover


def run(options: dict[str, Any]) -> list[dict[str, Any]]:
    quick = bool(options.get("quick"))
    rng = np.random.default_rng(int(options.get("seed", 0)))
    cam = PinholeCamera(SIZE, SIZE, 220.0, 220.0, SIZE / 2, SIZE / 2, np.eye(3), np.zeros(3))
    counts = [10_000] if quick else [10_000, 50_000, 200_000]
    tiles = [8] if quick else [8, 16]
    backends = [(b, d) for b, d in BACKENDS if d == "cpu" or torch.cuda.is_available()]
    rows = []
    for n in counts:
        scene = random_scene(n, rng)
        for tile in tiles:
            group = []
            for backend, device in backends:  # side by side: same scene, same moment
                fwd, bwd, cover = time_render(scene, cam, tile, 2 if quick else 3, backend,
                                              device)
                where = "" if device == "cpu" else f" {device}"
                group.append({"method": f"{backend}{where} tiles {tile}px",
                              "setting": f"{n // 1000}k splats", "backend": backend,
                              "device": device, "splats": n, "tile": tile,
                              "ms_forward": round(fwd, 1), "ms_backward": round(bwd, 1),
                              "ms_forward_backward": round(fwd + bwd, 1),
                              "mean_alpha": round(cover, 3),
                              "threads": torch.get_num_threads()})
            torch_cpu = group[1]["ms_forward_backward"]
            for row in group:  # speedup over the vectorised torch path on the CPU
                row["speedup"] = round(torch_cpu / max(row["ms_forward_backward"], 1e-9), 2)
            rows.extend(group)
    return rows


def notes(options: dict[str, Any]) -> list[str]:
    return [f"{SIZE}x{SIZE} pinhole, SH degree 3, torch {torch.__version__}, "
            f"{torch.get_num_threads()} thread(s); wall time, median of runs after a warm-up"]
