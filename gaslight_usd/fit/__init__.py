"""Fitting HDR Gaussian splats to posed linear HDR views.

``load_fit_data(hdr_dir, poses, working_size=...)`` -> :class:`FitData` (checked);
``fit_splats(data, config, seed, progress, checkpoint, resume)`` ->
:class:`FitResult` (scene, metrics, history); presets in :data:`PRESETS`.
"""

from .data import FitData, load_fit_data
from .presets import PRESETS, FitConfig, preset
from .trainer import FitResult, fit_splats

__all__ = ["PRESETS", "FitConfig", "FitData", "FitResult", "fit_splats", "load_fit_data",
           "preset"]
