"""Fitting presets: how hard to try. ``fast`` is what the README example uses.

Each preset names a working size (the views' long side in pixels), not a factor
of the photos' size: a 12 MP phone photo and the example's 480 x 360 render are
fitted at the same size, so time and memory follow the preset, not the camera.
The sizes keep the example's fits as they were measured (480 x 360 views: fast
at 120 x 90, balanced at 240 x 180, best at its own size) and keep a 24-photo
set inside the time goals of issue 23 (``gaslight2usd bench --suite scale``):
a fit's cost grows with its pixels, so ``balanced`` at 1024 would take about
18 times its 240-pixel time.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from typing import Any

PLANE_PRIOR_MODES = ("auto", "on", "off")
"""``FitConfig.plane_prior``'s values."""


@dataclass(frozen=True)
class FitConfig:
    working_size: int = 240
    """Long side (pixels) the views are shrunk to before fitting (area average; never
    enlarged; 0: the views' own size)."""
    iterations: int = 2000
    budget: int = 100_000
    """Most splats kept."""
    init_points: int = 20_000
    triangulate: bool = True
    """Triangulate sparse points from the HDR views when the poses carry none."""
    max_sh_degree: int = 3
    sh_raise_every: int = 500
    """Steps between raising the active SH degree by one."""
    densify_from: float = 0.1
    densify_until: float = 0.6
    """Densification window as fractions of the iterations."""
    densify_every: int = 100
    grad_threshold: float = 0.0002
    """Mean view-space (NDC) gradient over which a splat is cloned or split."""
    percent_dense: float = 0.01
    min_opacity: float = 0.005
    max_scale: float = 0.5
    """Splats larger than this fraction of the scene extent are pruned (each densify
    round)."""
    max_final_scale: float = 0.2
    """Splats still larger than this fraction of the scene extent when training ends are
    cut (0: none). A fit leaves a few dozen blobs a metre wide, faint or wall-coloured,
    where few views look through them (in the middle of a room, behind the cameras):
    harmless in the photos, but a probe inside one sees the room through it (from true
    HDR views the example's lamp was 0.2-0.9 stops short at its probes, its own splats
    within 0.25 stops). Cutting them during
    training (``max_scale`` 0.2) changed every fit's course (``bulb``, ``panels`` lost
    lights); cut at the end they cost the held-out views what the fit's metrics
    ``oversized_cut`` report (``gaslight2usd bench --suite chain``)."""
    max_final_medians: float = 4.0
    """...and larger than this many times the fit's median splat: only blobs that are
    outliers in their own fit are cut (a coarse fit of a small set, every splat wide,
    loses nothing; the chain bench's rooms: median 0.07-0.08 m, limit 0.34 m)."""
    min_improvement: float = 0.005
    """Relative held-out improvement under which a densification round counts as idle."""
    patience: int = 2
    """Idle densification rounds in a row after which no more splats are added."""
    target_error: float = 0.0
    """Stop once the held-out log-luminance RMSE (stops) is below this (0: never)."""
    holdout_every: int = 8
    ssim_weight: float = 0.2
    log_weight: float = 0.0
    clip_bounds: bool = True
    """Fit clipped photo pixels as lower bounds (:func:`.losses.bounded_l1`), not as targets."""
    infer_power: bool = True
    """After the fit, rescale each clipped compact light (a bulb, a small panel) by the power
    the surfaces it lights imply, as the photos measured them (:mod:`.power`), never under
    the uplift's fill (a lower bound for a clipped light); windows and lights a view
    measured keep their power. ``gaslight2usd bench --suite chain`` measures it (power
    errors per light)."""
    fine_power: bool = True
    """Where no view clipped, brighten each compact light the views measured so that,
    drawn finer than the fitting size (HDRIs, probes), it keeps the power its views
    measured (:mod:`.fine_power`); off: the splats as fitted."""
    redraw_flat_lights: bool = True
    """After the fit, redraw each window or panel a view measured (not clipped) whose
    rectangle the views outlined on a wall or ceiling as a flat, even emitter there, at
    the power the training views drew (:mod:`gaslight_usd.fit.flat_redraw`: the fitted blobs
    draw it too bright from close by); off: the splats as fitted."""
    clip_fill_weight: float = 0.1
    """How strongly clipped pixels pull towards the uplift's fill (1 with ``clip_bounds``
    off is the old behaviour: the fill fitted like a measurement)."""
    plane_prior: str = "auto"
    """``on``: put each surface-fill pixel on its sparse neighbours' plane
    (:func:`.init.fill_depths`) and keep the splats near the walls and ceiling the
    initial points find on those planes, flat along them, with the bright clumps floating
    in front of a lit patch (a window) brought back onto it (:mod:`.planes`); ``off``:
    none of it (the neighbours' median depth); ``auto`` (the default): on where no view
    clipped (merged brackets, true HDR: every light measured), off where some did. From
    true HDR views it lifts the probes near a window most on the chain bench's held-out
    rooms; from clipped photos the lights' handling (outline seeds, sunk and
    one-photo lights, the lit-surface test, the weighing) still leans on the old fill's
    geometry (a ceiling panel read as a lit patch of ceiling, a lamp weighed over), so
    there it stays off unless asked for. Measured by ``gaslight2usd bench
    --suite chain --method "truth HDR, planes off" --method "recursive, planes on"``
    (``planes_held``, ``floaters_on_planes``, ``wall_offset_m``; docs/measurements.md)."""
    flatness_weight: float = 0.01
    """Weight of the held splats' thickness along their plane
    (:meth:`.planes.PlanePrior.flatness`)."""
    elongation_limit: float = 4.0
    """Largest-to-middle scale ratio above which ``elongation_weight`` penalises a splat."""
    elongation_weight: float = 0.0
    """Weight of the needle penalty (:func:`.losses.elongation_penalty`; 0: off)."""
    lr_means: float = 1.6e-4
    lr_means_final: float = 1.6e-6
    lr_scales: float = 5e-3
    lr_quats: float = 1e-3
    lr_opacity: float = 5e-2
    lr_colour: float = 1e-2
    lr_sh: float = 2.5e-3
    init_opacity: float = 0.1
    backdrop_tiles: int = 3000
    """Tiles over the splats' box; those no training view sees are kept (0: no backdrop)."""
    refine_poses: bool = False
    """Optimise small corrections to the training views' poses with the splats."""
    lr_pose_rotation: float = 1e-3
    """Adam step of the pose corrections' rotation (radians)."""
    lr_pose_translation: float = 2e-4
    """Adam step of their translation (fraction of the scene extent)."""
    antialiased: bool = True
    """Fit and draw with the opacity-compensated dilation (Mip-Splatting's 2D filter): a
    light smaller than a fitting pixel keeps its power in any other camera (HDRIs, probes,
    close-ups). Without it the plain dilation inflates sub-pixel splats in the training
    views, the fit makes them dim to match, and drawn finer the light loses power
    (``tests/test_fit.py``; ``gaslight2usd bench --suite chain --scene bulb``)."""
    checkpoint_every: int = 200
    background: float = 0.0
    """Radiance behind the splats (0: a closed set such as a room)."""
    random_background: float = 0.0
    """Each step composites the training view over a random colour, each channel uniform
    in [0, this x the training views' mean level] (0: over ``background``). A fit that may
    show the black background through its surfaces leaves them translucent (the example's
    ``fast`` fit covers 0.83 of its training pixels' alpha without it, 0.98 with 0.5), and
    whatever lies behind them from another viewpoint (the backdrop, splats seen from
    elsewhere) then shines through. The presets use 0.5 (measured in the README)."""

    def __post_init__(self) -> None:
        if self.plane_prior not in PLANE_PRIOR_MODES:
            raise ValueError(f"plane_prior {self.plane_prior!r}: choose from "
                             f"{', '.join(PLANE_PRIOR_MODES)}")

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    def updated(self, **changes: Any) -> FitConfig:
        return replace(self, **{k: v for k, v in changes.items() if v is not None})


PRESETS: dict[str, FitConfig] = {
    "fast": FitConfig(working_size=120, iterations=300, budget=12_000, init_points=4_000,
                      max_sh_degree=1, sh_raise_every=150, densify_every=40,
                      lr_means=4e-4, lr_colour=2e-2, lr_opacity=5e-2, checkpoint_every=100,
                      random_background=0.5),
    "balanced": FitConfig(working_size=240, iterations=2500, budget=100_000, init_points=20_000,
                          max_sh_degree=2, sh_raise_every=600, random_background=0.5),
    "best": FitConfig(working_size=2048, iterations=6000, budget=300_000, init_points=40_000,
                      max_sh_degree=3, sh_raise_every=1000, densify_until=0.5,
                      checkpoint_every=500, random_background=0.5),
}


UPLIFT_MIN_SIZE = 512
"""Smallest long side ``run`` uplifts photos at. The fast predictor measures its regions
in units of the image size, but a lamp a few pixels wide at 120 pixels has no shape
left to read; uplifting at 512 costs little (about a quarter megapixel a photo)."""


def uplift_size(config: FitConfig) -> int:
    """The long side ``run`` uplifts photos at for a fit with ``config`` (0: full size):
    the fit's working size, but at least :data:`UPLIFT_MIN_SIZE`."""
    if config.working_size <= 0:
        return 0
    return max(config.working_size, UPLIFT_MIN_SIZE)


SFM_OPTIONS: dict[str, dict[str, int]] = {
    "fast": {"max_image_size": 640, "max_features": 1024},
    "balanced": {"max_image_size": 640, "max_features": 8192},
    "best": {"max_image_size": 1600, "max_features": 8192},
}
"""SfM feature size (long side, pixels) and most SIFT features per photo that ``run``
uses with each preset. Matching grows with the square of the features' count. On the
example enlarged to 12 MP, 640 px keeps the pose accuracy of the photos as shot while
larger sizes lost a camera, and ``fast``'s count is about what the photos as shot have;
``best`` keeps COLMAP's usual 1600 for real photos' finer detail. Measured with
``gaslight2usd bench --suite poses --megapixels 12`` (docs/measurements.md)."""


def sfm_options(name: str) -> dict[str, int]:
    """The SfM options ``run`` uses with preset ``name`` (``best``'s for an unknown one)."""
    return dict(SFM_OPTIONS.get(name, SFM_OPTIONS["best"]))



def preset(name: str) -> FitConfig:
    if name not in PRESETS:
        raise KeyError(f"unknown preset {name!r}; choose from {', '.join(PRESETS)}")
    return PRESETS[name]
