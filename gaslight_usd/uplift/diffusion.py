"""The GaSLight diffusion predictor (bring your own weights; optional extra).

GaSLight fine-tunes Stable Diffusion 1.5 with the IC-Light checkpoint to
render a photo 2 EV darker (prompt "dark") or brighter ("bright"): the
encoded photo is VAE-encoded and concatenated to the noisy latent (8 input
channels), 20 sampler steps at 512x512. The public checkpoint is a
PyTorch-Lightning ``.ckpt`` that users download themselves from the authors'
release (see the project README); nothing is downloaded here.

Needs the optional packages ``torch`` and ``diffusers`` (and ``transformers``
for the text encoder). Weights: ``--weights PATH`` or ``$GASLIGHT_WEIGHTS``:
either a diffusers folder (``unet/``, ``vae/``, ``text_encoder/``,
``tokenizer/``, ``scheduler/``) or a single ``.ckpt``/``.safetensors`` file
converted with diffusers' single-file loader. Runs on the GPU when one is
present; on the CPU it works but is slow (minutes per step), with a warning.

:func:`tiny_components` builds a randomly initialised network of the same
structure (for testing the plumbing without weights).
"""

from __future__ import annotations

import importlib.util
import logging
import os
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from .curves import Curve

log = logging.getLogger(__name__)
ENV_WEIGHTS = "GASLIGHT_WEIGHTS"
PROMPTS = {"darker": "dark", "brighter": "bright"}
RESOLUTION = 512
STEPS = 20


def diffusers_available() -> bool:
    return all(importlib.util.find_spec(m) is not None for m in ("torch", "diffusers"))


def _require() -> None:
    if not diffusers_available():
        raise InputError("the diffusion predictor needs the optional packages torch and "
                         "diffusers (pip install diffusers transformers); use --predictor "
                         "fast for the built-in CPU predictor")


def tiny_components(seed: int = 0) -> dict[str, Any]:
    """A randomly initialised UNet/VAE/text encoder shaped like the real ones, tiny."""
    _require()
    import torch
    from diffusers import AutoencoderKL, DDIMScheduler, UNet2DConditionModel

    torch.manual_seed(seed)
    unet = UNet2DConditionModel(
        sample_size=8, in_channels=8, out_channels=4, layers_per_block=1,
        block_out_channels=(8, 16), down_block_types=("CrossAttnDownBlock2D", "DownBlock2D"),
        up_block_types=("UpBlock2D", "CrossAttnUpBlock2D"), cross_attention_dim=8,
        attention_head_dim=2, norm_num_groups=4)
    vae = AutoencoderKL(in_channels=3, out_channels=3, latent_channels=4,
                        block_out_channels=(8,), norm_num_groups=4,
                        down_block_types=("DownEncoderBlock2D",),
                        up_block_types=("UpDecoderBlock2D",))
    return {"unet": unet, "vae": vae, "scheduler": DDIMScheduler(),
            "text_embeddings": {p: torch.randn(1, 4, 8) for p in PROMPTS.values()}}


class DiffusionPredictor:
    """Latent diffusion conditioned on the encoded photo (IC-Light style)."""

    name = "diffusion"

    def __init__(self, weights: str | Path | None = None, device: str | None = None,
                 components: dict[str, Any] | None = None, steps: int = STEPS,
                 resolution: int = RESOLUTION, seed: int = 0):
        _require()
        import torch

        self.device = device or ("cuda" if torch.cuda.is_available() else "cpu")
        if self.device == "cpu":
            log.warning("the diffusion predictor runs on the CPU: expect minutes per step")
        self.steps, self.resolution, self.seed = steps, resolution, seed
        if components is None:
            weights = weights or os.environ.get(ENV_WEIGHTS)
            if not weights:
                raise InputError("the diffusion predictor needs weights: --weights PATH or "
                                 f"${ENV_WEIGHTS} (the GaSLight checkpoint; see the README)")
            components = self._load(Path(weights))
        self.c = components
        for key in ("unet", "vae"):
            self.c[key].to(self.device).eval()

    def _load(self, path: Path) -> dict[str, Any]:
        from diffusers import StableDiffusionPipeline

        if not path.exists():
            raise InputError("no such weights file or folder", path)
        try:
            pipe = (StableDiffusionPipeline.from_pretrained(str(path)) if path.is_dir() else
                    StableDiffusionPipeline.from_single_file(str(path)))
        except Exception as exc:  # diffusers raises many kinds
            raise InputError(f"cannot load diffusion weights: {exc}", path) from exc
        import torch

        with torch.no_grad():
            emb = {}
            for prompt in PROMPTS.values():
                ids = pipe.tokenizer(prompt, padding="max_length", return_tensors="pt",
                                     max_length=pipe.tokenizer.model_max_length).input_ids
                emb[prompt] = pipe.text_encoder(ids)[0]
        return {"unet": pipe.unet, "vae": pipe.vae, "scheduler": pipe.scheduler,
                "text_embeddings": emb}

    def _run(self, encoded: np.ndarray, prompt: str) -> np.ndarray:
        import torch
        import torch.nn.functional as F

        unet, vae, sched = self.c["unet"], self.c["vae"], self.c["scheduler"]
        h, w = encoded.shape[:2]
        x = torch.from_numpy(np.ascontiguousarray(encoded.transpose(2, 0, 1)))[None]
        x = F.interpolate(x.float(), size=(self.resolution, self.resolution), mode="bilinear",
                          align_corners=False).to(self.device) * 2 - 1
        gen = torch.Generator(device="cpu").manual_seed(self.seed)
        scale = getattr(vae.config, "scaling_factor", 0.18215)
        with torch.no_grad():
            cond = vae.encode(x).latent_dist.mode() * scale
            latent = torch.randn(cond.shape, generator=gen).to(self.device)
            emb = self.c["text_embeddings"][prompt].to(self.device)
            sched.set_timesteps(self.steps)
            latent = latent * sched.init_noise_sigma
            for t in sched.timesteps:
                inp = torch.cat([sched.scale_model_input(latent, t), cond], dim=1)
                noise = unet(inp, t, encoder_hidden_states=emb).sample
                latent = sched.step(noise, t, latent).prev_sample
            out = vae.decode(latent / scale).sample
            out = F.interpolate(out, size=(h, w), mode="bilinear", align_corners=False)
        return ((out[0].permute(1, 2, 0).cpu().numpy() + 1) / 2).clip(0, 1).astype(np.float32)

    def darker(self, encoded: np.ndarray, curve: Curve, ev: float) -> np.ndarray:
        return self._run(encoded, PROMPTS["darker"])

    def brighter(self, encoded: np.ndarray, curve: Curve, ev: float) -> np.ndarray:
        return self._run(encoded, PROMPTS["brighter"])


PREDICTORS = {
    "diffusion": (DiffusionPredictor,
                  "GaSLight diffusion model (optional diffusers; bring your own weights)"),
}
"""The predictors this module offers: name -> (factory, description); see
:mod:`.predictors`."""
