"""Fit HDR Gaussian splats to posed linear HDR views (GaSLight's second half).

The loop is 3DGS's (Kerbl et al. 2023) on linear HDR targets: one view per
step, loss L1(HDR) + 0.2 (1 - SSIM(clamped)), Adam, densify by view-space
gradient and prune; each step's render is composited over a random colour
(``random_background``), so the fit cannot leave surfaces see-through. It adds
no more than the scene needs:

- densification runs only while the held-out views still improve (relative
  gain of the held-out log-luminance RMSE >= ``min_improvement`` between two
  densification rounds) and never past ``budget`` splats;
- a held-out error under ``target_error`` ends the fit early;
- splats that contribute (almost) nothing to any training view are pruned;
- the SH degree is raised step by step and the exported degree is the lowest
  whose held-out error is within 1% of the best.

With ``refine_poses`` the training views' poses are corrected along with the
splats (:mod:`.pose_refine`); held-out views keep theirs.

It starts from real geometry when it can: poses without points get points
triangulated from the HDR views (:mod:`.triangulate`), spread over the
surfaces the views see (:mod:`.init`). After the fit, what no training view
saw is closed by a backdrop of flat splats (:mod:`.backdrop`), inside the
budget, so panoramas rendered in the scene have no black holes.
"""

from __future__ import annotations

import os
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ..cameras import PinholeCamera
from ..colour import luminance_weights
from ..devices import resolve_device
from ..errors import FitDiverged, InputError
from ..flat_outlines import Outline, lit_masks, plane_outlines
from ..light_shapes import drawn_on_outline, outlined_panel, panel_of
from ..outline_edges import refine_outlines
from ..poses.agreement import pose_agreement
from ..progress import Progress
from ..render import render
from ..sightings import sight_lights, view_whites
from ..splats import SplatScene
from .backdrop import concatenate, unseen_backdrop
from .camera_floaters import HELD_OUT_SLACK_STOPS, camera_floaters
from .checkpoint import load_checkpoint, save_checkpoint
from .contribution import contributions
from .data import FitData
from .exposure_check import exposure_outliers
from .fine_power import (
    MIN_VIEWS,
    FinePower,
    matched_light,
    measuring_views,
    rows_after,
    with_fine_power,
)
from .flat_redraw import Redrawn, redraw_flat_lights
from .fog import fog_splats
from .frame_edge import CutLight, cut_lights, white_ratios
from .frames_meet import (
    WHITE_MULTIPLE,
    bulb_sightings,
    frame_and_seed,
    frames_meeting,
    measuring_sightings,
    moved_to_meeting,
)
from .holes import fill_holes
from .init import initial_points, neighbour_scales
from .light_seeds import (
    MEASURED_LIGHT_RATIO,
    LightSeed,
    LightSeedPoints,
    find_light_seeds,
    measured_level,
    measured_light_seeds,
    seed_points,
)
from .lit_floor import FLAT, LitFloor, floor_discs, floor_plane, room_vertical, views_lit_floor
from .losses import elongation_penalty, fit_loss, held_out_errors
from .model import SplatModel
from .planes import (
    KEEP_OUT_SIZES,
    Plane,
    PlanePrior,
    ceiling_at_sparse_points,
    ceiling_from_walls,
    far_walls,
    find_planes,
    on_a_plane,
    on_planes,
    room_box,
    sparse_axes,
)
from .pose_refine import PoseRefiner
from .power import LightPower, infer_light_power, light_sighting, lights_to_weigh
from .presets import FitConfig
from .shade_bands import ClosedBand, box_vertical, close_hidden_bands
from .sheets import SHEET_THIN_SHARE, sheet_splats, squashed
from .single_view import BRIGHT_RATIO, single_view_lights
from .sunk_lights import RULES, SurfacedLights, surface_sunk_lights
from .triangulate import triangulate_views

FLOOR_TOLERANCE = 0.005
"""A start's splat within this share of the cameras' extent of the lit floor lies on it
(the fill puts the patch's pixels on it exactly, its neighbours' within a centimetre)."""
MIN_CONTRIBUTION = 0.02
"""Pixel-equivalents of blend weight (x relative brightness) under which a splat is pruned."""
HOLES_SHARE = 0.1
"""At most this share of the budget goes to the views' empty patches (:mod:`.holes`); a
fit at its budget makes room by pruning the splats that contribute least."""


@dataclass
class FitResult:
    scene: SplatScene
    metrics: dict[str, Any]
    history: list[dict[str, Any]] = field(default_factory=list)
    cameras: list[PinholeCamera] = field(default_factory=list)
    """Every view's camera as the fit ended (refined poses for training views)."""


def scene_extent(data: FitData, train: list[int]) -> float:
    centres = np.array([data.cameras[i].center for i in train])
    extent = 1.1 * float(np.linalg.norm(centres - centres.mean(0), axis=1).max())
    if extent < 1e-3 and len(data.model.points):
        extent = float(np.linalg.norm(data.model.points - centres.mean(0), axis=1).max())
    return max(extent, 1e-2)


def _order(step: int, n: int, seed: int) -> int:
    """The view of a step: a fresh seeded permutation of the training views each epoch."""
    epoch, pos = divmod(step, n)
    return int(np.random.default_rng([seed, epoch]).permutation(n)[pos])


class Trainer:
    def __init__(self, data: FitData, config: FitConfig, seed: int = 0,
                 progress: Progress | None = None, checkpoint: Path | None = None,
                 device: str | torch.device = "cpu"):
        self.data, self.cfg, self.seed = data, config, seed
        self.progress = progress or Progress(quiet=True)
        self.checkpoint = Path(checkpoint) if checkpoint else None
        self.device = device
        for name, image in zip(data.names, data.images, strict=True):
            bad = int(np.count_nonzero(~np.isfinite(image)))
            if bad:  # files are checked as read; views handed over in memory are not
                raise InputError(f"view {name} holds {bad} NaN or infinite value(s)")
        self.train, self.held = data.split(config.holdout_every)
        self.extent = scene_extent(data, self.train)
        self.targets = [torch.as_tensor(im, device=device) for im in data.images]
        self.floors = [None if not config.clip_bounds or f is None
                       else torch.as_tensor(f, device=device)
                       for f in data.loss_floors()]
        self.ceilings = [None if not config.clip_bounds or (c := data.ceiling(i)) is None
                         else torch.as_tensor(c, device=device)
                         for i in range(len(data.images))]
        # Rec.709's weights when the space is unnamed or unknown (in-memory scenes)
        self.y_weights = torch.as_tensor(luminance_weights(data.colour_space or None,
                                                           fallback=True), device=device)
        # the training views' mean: the random background's scale and the idle-prune level
        self.mean_level = float(np.mean([data.images[i].mean() for i in self.train])) or 1.0
        self.history: list[dict[str, Any]] = []
        self._seeds: list[LightSeed] | None = None
        self._measured_seeds: list[LightSeed] | None = None
        clipped = self._view_whites(self.train) if config.plane_prior != "off" else None
        self.use_planes = config.plane_prior == "on" or (config.plane_prior == "auto"
                                                         and clipped is None)
        """Whether the fill and the fit keep to the walls' planes (``FitConfig.plane_prior``)."""
        self._plane_white = (None if clipped is None or not config.clip_bounds
                             else float(np.median(clipped)))
        """Over this luminance a splat is a clipped light's, free of the planes."""

    # -- state -------------------------------------------------------------------
    def _fresh(self) -> None:
        cfg = self.cfg
        torch.manual_seed(self.seed)
        rng = np.random.default_rng(self.seed)
        cams = [self.data.cameras[i] for i in self.train]
        imgs = [self.data.images[i] for i in self.train]
        names = [self.data.names[i] for i in self.train]
        floors = [self.data.floor(i) for i in self.train] if cfg.clip_bounds else None
        up = np.mean([-c.R[1] for c in cams], axis=0)
        self.lit_floor = self._find_lit_floor(cams, up)
        self.lit_floor_info = None if self.lit_floor is None else self.lit_floor.as_dict()
        """What the fit's metrics report of it (kept through a checkpoint)."""
        pts, cols, how = initial_points(self._init_model(), cams, imgs, names,
                                        min(cfg.init_points, cfg.budget), rng, floors,
                                        self.y_weights.cpu().numpy(), self._seeded_lights(),
                                        planar_fill=self.use_planes, room_floor=self.lit_floor)
        lrs = {"means": cfg.lr_means * self.extent, "quats": cfg.lr_quats,
               "log_scales": cfg.lr_scales, "opacity_logits": cfg.lr_opacity,
               "log_colour": cfg.lr_colour, "sh_rel": cfg.lr_sh}
        self.model = SplatModel.initial(pts, cols, neighbour_scales(pts), cfg.init_opacity, lrs,
                                        self.device)
        self.model.antialiased = cfg.antialiased
        self._discs_on_floor(pts)
        self.planes = None
        centres = np.array([c.center for c in cams])
        found = find_planes(pts, centres, np.random.default_rng([self.seed, 11]))
        # the box square to the triangulated points' directions: the fill from uplifted
        # photos leans it (the plane prior keeps the fill's own planes: square to those
        # directions they cost true HDR views' fits; docs/measurements.md, session 53)
        axes = sparse_axes(np.asarray(self._init_model().points, np.float64),
                           np.random.default_rng([self.seed, 17]))
        boxed = found if axes is None else find_planes(
            pts, centres, np.random.default_rng([self.seed, 11]), axes)
        self.room_planes: list[Plane] = room_box(boxed[0], len(pts))
        """The room's box among the large planes of the initial points, along the sparse
        points' directions (:func:`.planes.room_box`, :func:`.planes.sparse_axes`), with
        the ceiling where its walls stop if none was found
        (:func:`.planes.ceiling_from_walls`), the ceiling then put at the sparse points on
        it (:func:`.planes.ceiling_at_sparse_points`), and a window's wall too sparse to be found
        (:func:`.planes.far_walls`) and a floor the views' lit patch pins
        (:mod:`.lit_floor`): the bound on a sunk light's move and the planes a window's
        splats are put on (:mod:`.sunk_lights`)."""
        ceiling = ceiling_from_walls(self.room_planes, pts, found[1], up)
        if ceiling is not None:
            self.room_planes.append(ceiling)
        self.room_planes = ceiling_at_sparse_points(self.room_planes,
                                                    self._init_model().points, found[1], up)
        self.room_planes += far_walls(self.room_planes, pts, centres, found[1], up)
        floor = floor_plane(self.lit_floor, self.room_planes, pts)
        if floor is not None:
            self.room_planes.append(floor)
        if self.use_planes:
            self.planes = PlanePrior(*found, self.device)
            self._assign_planes()
        self.refiner = (PoseRefiner(cams, cfg.lr_pose_rotation,
                                    cfg.lr_pose_translation * self.extent, self.device)
                        if cfg.refine_poses else None)
        self.step = 0
        self.init_method = how
        self.generator = torch.Generator().manual_seed(self.seed)
        self.densifying = True
        self.last_error: float | None = None
        self.idle_rounds = 0
        self.elapsed = 0.0
        self.floaters_moved = 0
        """Light splats :meth:`_surface_floaters` moved (reported with the fit's metrics)."""
        self.frames_met: list[dict[str, Any]] = []
        """The bulbs :meth:`_placed_by_frames` moved at the end (reported likewise)."""
        self.holes_filled: dict[str, Any] = {"splats": 0, "freed": 0, "empty_pixels": {}}
        self.fog_dropped = 0
        """Splats dropped as fog midway (:meth:`_drop_fog`)."""
        """What :meth:`_fill_holes` added (reported with the fit's metrics)."""
        self._reset_stats()

    @torch.no_grad()
    def _discs_on_floor(self, pts: np.ndarray) -> None:
        """The start's splats on the lit floor as discs lying on it
        (:func:`.lit_floor.floor_discs`)."""
        on, quat = floor_discs(pts, self.lit_floor, FLOOR_TOLERANCE * self.extent)
        if not len(on):
            return
        index = torch.as_tensor(on, device=self.device)
        self.model.t["quats"][index] = torch.as_tensor(quat, dtype=torch.float32,
                                                       device=self.device)
        self.model.t["log_scales"][index, 2] += float(np.log(FLAT))

    def _find_lit_floor(self, cams: list, up: np.ndarray) -> LitFloor | None:
        """The floor the training views' lit patch pins (:mod:`.lit_floor`), where the
        sparse points miss it."""
        points = np.asarray(self._init_model().points, np.float64)
        vertical = room_vertical(points, up, np.random.default_rng([self.seed, 13]))
        measuring = set(self.data.measures_highlights())
        return views_lit_floor(cams, [self.data.images[i] for i in self.train],
                               [self.data.floor(i) for i in self.train],
                               [i in measuring for i in self.train],
                               self.y_weights.cpu().numpy(), vertical, points)

    def _init_model(self):
        """The poses' model, with points triangulated from the views when it has none
        (made once: the exposure check at the end reads its points too)."""
        if getattr(self, "_points_model", None) is not None:
            return self._points_model
        model = self.data.model
        if len(model.points) < 16 and self.cfg.triangulate and self.data.paths:
            by_stem = {p.stem: p for p in self.data.paths}
            views = {n: by_stem[Path(n).stem] for n in model.names}
            model = triangulate_views(model, views, self.progress) or model
        self._points_model = model
        return model

    def _assign_planes(self) -> None:
        """Hold the splats near the planes on them (:mod:`.planes`), all but those over
        the photos' white where some photo clipped: a clipped light's depth is a guess
        the lights' machinery (seeds, sunk lights, one-photo lights) settles, so it is
        only kept in front of the wall, not pinned among the wall's splats. Bright
        floaters in front of a lit patch of a wall go onto it
        (:func:`.planes.bright_floaters`), bar the seeded compact lights'."""
        lum = torch.exp(self.model.t["log_colour"].detach()) @ self.y_weights
        free = lum > self._plane_white if self._plane_white is not None else None
        lights = [(seed.position, seed.size) for seed in self._light_seeds()]
        # a measured light flush with a plane (a ceiling panel) is the plane's light:
        # the floater rule puts its floating splats back on it
        lights += [(seed.position, seed.size) for seed in self._measured_lights()
                   if not on_a_plane(seed.position, 2.0 * seed.size, self.planes.planes)]
        self.planes.assign(self.model.t["means"], free, lum, lights)

    def _reset_stats(self) -> None:
        n = self.model.count
        self.grad_sum = torch.zeros(n, device=self.device)
        self.grad_count = torch.zeros(n, device=self.device)

    def _state(self) -> dict:
        return {"model": self.model.state_dict(), "step": self.step, "seed": self.seed,
                "config": self.cfg.as_dict(), "views": self.data.names,
                "init_method": self.init_method, "generator": self.generator.get_state(),
                "densifying": self.densifying, "last_error": self.last_error,
                "idle_rounds": self.idle_rounds,
                "grad_sum": self.grad_sum, "grad_count": self.grad_count,
                "history": self.history, "elapsed": self.elapsed,
                "floaters_moved": self.floaters_moved,
                "holes_filled": self.holes_filled,
                "fog_dropped": self.fog_dropped,
                "room_planes": [asdict(plane) for plane in self.room_planes],
                "lit_floor": self.lit_floor_info,
                "poses": self.refiner.state_dict() if self.refiner else None,
                "planes": self.planes.state_dict() if self.planes else None}

    def _restore(self, state: dict) -> bool:
        if (state.get("config") != self.cfg.as_dict() or state.get("seed") != self.seed
                or state.get("views") != self.data.names):
            return False
        self.model = SplatModel.from_state(state["model"], self.device)
        self.model.antialiased = self.cfg.antialiased
        self.step, self.init_method = state["step"], state["init_method"]
        self.generator = torch.Generator()
        self.generator.set_state(state["generator"])
        self.densifying, self.last_error = state["densifying"], state["last_error"]
        self.idle_rounds = state["idle_rounds"]
        self.grad_sum = state["grad_sum"].to(self.device)
        self.grad_count = state["grad_count"].to(self.device)
        self.history, self.elapsed = state["history"], state["elapsed"]
        self.floaters_moved = int(state.get("floaters_moved", 0))
        self.frames_met = []  # filled at the end, after any checkpoint
        self.holes_filled = state.get("holes_filled", {"splats": 0, "freed": 0, "empty_pixels": {}})
        self.fog_dropped = int(state.get("fog_dropped", 0))
        self.room_planes = [Plane(**plane) for plane in state.get("room_planes", [])]
        self.lit_floor_info = state.get("lit_floor")
        self.planes = (PlanePrior.from_state(state["planes"], self.device)
                       if state.get("planes") is not None else None)
        self.refiner = None
        if state.get("poses") is not None:
            self.refiner = PoseRefiner([self.data.cameras[i] for i in self.train],
                                       self.cfg.lr_pose_rotation,
                                       self.cfg.lr_pose_translation * self.extent,
                                       self.device)
            self.refiner.load_state_dict(state["poses"])
        return True

    def cameras(self) -> list[PinholeCamera]:
        """Every view's camera now: training views with their refined poses, if refined."""
        cams = list(self.data.cameras)
        if self.refiner is not None:
            refined = self.refiner.cameras([cams[i] for i in self.train])
            for i, cam in zip(self.train, refined, strict=True):
                cams[i] = cam
        return cams

    # -- evaluation ----------------------------------------------------------------
    def evaluate(self, views: list[int], degree: int) -> dict[str, float]:
        errs = []
        params = self.model.params(degree)
        cams = self.cameras()
        with torch.no_grad():
            for i in views:
                pred = render(params, cams[i], background=self.cfg.background,
                              sh_degree=degree).image.cpu().numpy()
                errs.append(held_out_errors(pred, self.data.images[i]))
        return {k: float(np.mean([e[k] for e in errs])) for k in errs[0]}

    def _evaluate_scene(self, scene: SplatScene, views: list[int]) -> dict[str, float]:
        cams = self.cameras()
        errs = [held_out_errors(render(scene, cams[i], background=self.cfg.background,
                                       device=self.device).image.cpu().numpy(),
                                self.data.images[i]) for i in views]
        return {k: float(np.mean([e[k] for e in errs])) for k in errs[0]}

    def _training_background(self) -> float | tuple[float, float, float]:
        """The colour behind this step's view (see ``FitConfig.random_background``);
        drawn from (seed, step) alone, so a resumed fit draws the same colours."""
        if not self.cfg.random_background:
            return self.cfg.background
        level = self.cfg.random_background * self.mean_level
        rgb = np.random.default_rng([self.seed, self.step, 1]).uniform(0.0, level, 3)
        return tuple(float(v) for v in rgb)

    def active_degree(self) -> int:
        return min(self.cfg.max_sh_degree, self.step // max(self.cfg.sh_raise_every, 1))

    # -- densify and prune -----------------------------------------------------------
    def _densify_and_prune(self) -> None:
        cfg, m = self.cfg, self.model
        cap = cfg.budget - self._backdrop_reserve()
        if self.densifying and m.count < cap:
            mean_grad = self.grad_sum / self.grad_count.clamp_min(1)
            big = mean_grad >= cfg.grad_threshold
            room = cap - m.count
            if int(big.sum()) > room:
                top = torch.topk(torch.where(big, mean_grad, -1.0), room).indices
                big = torch.zeros_like(big)
                big[top] = True
            size = torch.exp(m.t["log_scales"].detach()).max(1).values
            small = size <= cfg.percent_dense * self.extent
            m.densify(big & small, big & ~small, self.generator)
        opac = torch.sigmoid(m.t["opacity_logits"].detach())
        size = torch.exp(m.t["log_scales"].detach()).max(1).values
        m.prune((opac < cfg.min_opacity) | (size > cfg.max_scale * self.extent))
        if self.planes is not None:  # new splats, new indices
            self._assign_planes()
            self.planes.snap(m.t["means"])
        self._reset_stats()

    def _backdrop_reserve(self) -> int:
        """Splats of the budget kept for the backdrop (a share of its tiles is unseen)."""
        return min(self.cfg.backdrop_tiles // 2, self.cfg.budget // 10)

    def _contribution_scores(self) -> torch.Tensor:
        """(N,) what each splat contributes to the training views: its blend weight, times
        its radiance over those views' mean level (:attr:`mean_level`) where brighter."""
        degree = self.active_degree()
        cams = self.cameras()
        weight, radiance = contributions(self.model.params(degree),
                                         [cams[i] for i in self.train], degree)
        return weight * torch.clamp(radiance / weight.clamp_min(1e-12) / self.mean_level,
                                    min=1.0)

    def _drop_fog(self) -> None:
        """Drop the broad faint splats in the room's open air (:mod:`.fog`) while the fit
        has steps left to refit the room without them. Only where views clipped: measured
        on the README's capture; fits of true HDR views or merged brackets are left as
        they were."""
        if not self.room_planes or self._view_whites(self.train) is None:
            return
        fog = fog_splats(self.model.to_scene(self.active_degree(), {}), self.room_planes,
                         self.extent)
        if not fog.any():
            return
        self.model.prune(torch.as_tensor(fog, device=self.device))
        if self.planes is not None:
            self._assign_planes()
        self.fog_dropped = int(fog.sum())

    def _squash_onto_planes(self, scene: SplatScene) -> tuple[SplatScene, int]:
        """The splats on the room's walls and ceiling squashed flat onto their planes
        (:mod:`.sheets`), lights left as they are; returns the scene and how many."""
        if not self.room_planes:
            return scene, 0
        rows, normals = sheet_splats(scene, self.room_planes, self.extent,
                                     exempt=self._bright_splats(scene))
        return squashed(scene, rows, normals, SHEET_THIN_SHARE * self.extent)

    def _prune_idle(self) -> int:
        """Prune splats that contribute next to nothing to the training views
        (:meth:`_contribution_scores`)."""
        idle = self._contribution_scores() < MIN_CONTRIBUTION
        self.model.prune(idle)
        if self.planes is not None:
            self._assign_planes()
        return int(idle.sum())

    def _cut_oversized(self, scene: SplatScene, backdrop: int
                       ) -> tuple[SplatScene, dict[str, Any]]:
        """Cut the fitted splats (not the last ``backdrop``) larger than ``max_final_scale``
        of the extent and ``max_final_medians`` of their median size (the docstrings say
        why) and say what that cost the held-out views (log-luminance RMSE, stops).
        After the lights are weighed: the weighing gathers
        light with the splats as fitted (cut before it, the blobs' shade lifted off the
        walls moved a lamp's factor 1.4 stops on ``room:11``)."""
        fitted = scene.count - backdrop
        size = scene.scales[:fitted].max(axis=1)
        limit = self.cfg.max_final_scale * self.extent
        if fitted and limit > 0:
            limit = max(limit, self.cfg.max_final_medians * float(np.median(size)))
        out: dict[str, Any] = {"splats": 0, "limit": round(limit, 5)}
        if limit <= 0:
            return scene, out
        big = np.zeros(scene.count, bool)
        big[:fitted] = size > limit
        scene, cost = self._without(scene, big)
        return scene, {**out, **cost}

    def _without(self, scene: SplatScene, drop: np.ndarray
                 ) -> tuple[SplatScene, dict[str, Any]]:
        """``scene`` without the splats ``drop`` (N,) and what that cost the held-out
        views (log-luminance RMSE, stops, before and after; the count alone where none)."""
        out: dict[str, Any] = {"splats": int(drop.sum())}
        if not out["splats"]:
            return scene, out
        views = self.held or self.train[:: max(1, len(self.train) // 4)]
        before = self._evaluate_scene(scene, views)["log_lum_rmse_stops"]
        scene = scene.subset(np.flatnonzero(~drop))
        after = self._evaluate_scene(scene, views)["log_lum_rmse_stops"]
        out.update(held_out_stops_before=round(before, 4), held_out_stops_after=round(after, 4))
        return scene, out

    def _drop_camera_floaters(self, scene: SplatScene, backdrop: int
                              ) -> tuple[SplatScene, dict[str, Any]]:
        """Drop the faint splats floating just in front of a camera (:mod:`.camera_floaters`;
        not the last ``backdrop``) and say what that cost the held-out views
        (log-luminance RMSE, stops); keep them (``refused``) where that is over
        :data:`.camera_floaters.HELD_OUT_SLACK_STOPS`. Last: the light rules before it
        (the weighing, the redraw) see the fit as it was."""
        drop = camera_floaters(scene, np.array([c.center for c in self.data.cameras]),
                               self.room_planes, self.extent, self.y_weights.cpu().numpy(),
                               fitted=scene.count - backdrop)
        dropped, out = self._without(scene, drop)
        if out["splats"] and (out["held_out_stops_after"] - out["held_out_stops_before"]
                              > HELD_OUT_SLACK_STOPS):
            return scene, {**out, "splats": 0, "refused": out["splats"]}
        return dropped, out

    def _choose_degree(self) -> tuple[int, dict[str, float]]:
        views = self.held or self.train[:: max(1, len(self.train) // 4)]
        top = self.active_degree()
        scores = {d: self.evaluate(views, d) for d in range(top + 1)}
        best = min(s["log_lum_rmse_stops"] for s in scores.values())
        for d in range(top + 1):
            if scores[d]["log_lum_rmse_stops"] <= best * 1.01 + 1e-9:
                return d, scores[d]
        return top, scores[top]

    # -- the loop ----------------------------------------------------------------------
    def run(self, resume: bool = False) -> FitResult:
        """Fit: train steps, a densify round every ``densify_every`` steps inside the
        densify window (held-out check, patience, stop at the target error), the lights
        drawn in front of a camera moved onto the room's surfaces at its end
        (:meth:`_surface_floaters`), then :meth:`_finish` (prune, SH degree, backdrop,
        the other light rules, lights' power, metrics)."""
        resumed, init_seconds = self._start(resume)
        t0 = time.perf_counter() - self.elapsed
        stop_reason = "iterations"
        while self.step < self.cfg.iterations:
            loss = self._train_step()
            if self._densify_due():
                if self._held_out_round(t0):
                    stop_reason = "target error"
                    break
                self._densify_and_prune()
            if self.step == self._floaters_step():
                self._surface_floaters()
                self._bulbs_to_frames_midway()
                self._drop_fog()
                self._fill_holes()  # densification has covered what it can by now
            self.progress.update(self.step, self.cfg.iterations, loss=loss,
                                 splats=self.model.count)
            if self.checkpoint is not None and self.step % self.cfg.checkpoint_every == 0:
                self.elapsed = time.perf_counter() - t0
                save_checkpoint(self.checkpoint, self._state())
        return self._finish(t0, stop_reason, resumed, init_seconds)

    def _start(self, resume: bool) -> tuple[bool, float]:
        """Continue from the checkpoint when asked and it matches, else a fresh start;
        returns (resumed, seconds the fresh start took)."""
        resumed = False
        if resume and self.checkpoint is not None:
            state = load_checkpoint(self.checkpoint)
            resumed = state is not None and self._restore(state)
            if state is not None and not resumed:
                self.progress.message("checkpoint is for other settings or views; starting over")
        init_start = time.perf_counter()
        if not resumed:
            self._fresh()
        elif self.step:
            self.progress.message(f"resuming at step {self.step}")
        return resumed, time.perf_counter() - init_start

    def _train_step(self) -> float:
        """One optimiser step on the step's view; gathers the densify gradients. Returns
        the loss."""
        cfg = self.cfg
        frac = self.step / max(cfg.iterations - 1, 1)
        lr0, lr1 = cfg.lr_means * self.extent, cfg.lr_means_final * self.extent
        self.model.set_lr("means", lr0 * (lr1 / lr0) ** frac)
        k = _order(self.step, len(self.train), self.seed)
        view = self.train[k]
        cam = self.data.cameras[view]
        out = render(self.model.params(self.active_degree()), cam,
                     background=self._training_background(), sh_degree=self.active_degree(),
                     pose=self.refiner.pose(k) if self.refiner else None)
        loss = fit_loss(out.image, self.targets[view], cfg.ssim_weight, cfg.log_weight,
                        self.floors[view], self.y_weights, cfg.clip_fill_weight,
                        self.ceilings[view])
        if cfg.elongation_weight:
            loss = loss + cfg.elongation_weight * elongation_penalty(
                self.model.t["log_scales"], cfg.elongation_limit)
        if self.planes is not None and cfg.flatness_weight:
            loss = loss + cfg.flatness_weight * self.planes.flatness(
                self.model.t["quats"], self.model.t["log_scales"])
        if not bool(torch.isfinite(loss)):
            raise FitDiverged(
                f"the fit diverged at step {self.step + 1} of {cfg.iterations} on view "
                f"{self.data.names[view]} (loss {float(loss.detach())}); nothing was written. A "
                "view with NaN or huge values, or a learning rate too high for this "
                "scene: check the views with 'gaslight2usd info', try another --seed")
        loss.backward()
        with torch.no_grad():
            g = out.means2d.grad
            if g is not None and len(g):
                g = g * torch.tensor([cam.width / 2.0, cam.height / 2.0], device=g.device)
                self.grad_sum.index_add_(0, out.index, g.norm(dim=1))
                self.grad_count.index_add_(0, out.index,
                                           torch.ones(len(out.index), device=g.device))
        self.model.step()
        if self.planes is not None:
            self.planes.snap(self.model.t["means"])
        if self.refiner is not None:
            self.refiner.step(k)
        self.step += 1
        return float(loss.detach())

    def _densify_due(self) -> bool:
        """Whether this step ends a densify round (inside the densify window)."""
        cfg = self.cfg
        first = int(cfg.densify_from * cfg.iterations)
        last = int(cfg.densify_until * cfg.iterations)
        return first <= self.step <= last and self.step % cfg.densify_every == 0

    def _held_out_round(self, t0: float) -> bool:
        """The held-out check of a densify round: record the error, stop adding splats
        after ``patience`` rounds without improvement. Returns whether the target error
        is reached (the fit stops)."""
        cfg = self.cfg
        if not (self.held and self.densifying):
            return False
        err = self.evaluate(self.held, self.active_degree())["log_lum_rmse_stops"]
        self.history.append({"step": self.step, "splats": self.model.count,
                             "seconds": round(time.perf_counter() - t0, 2),
                             "held_out_log_lum_rmse": err})
        idle = self.last_error is not None and err > self.last_error * (1 - cfg.min_improvement)
        self.idle_rounds = self.idle_rounds + 1 if idle else 0
        if self.idle_rounds >= cfg.patience:
            self.densifying = False
            self.progress.message(f"step {self.step}: held-out error stopped "
                                  f"improving ({err:.4f}); no more splats added")
        self.last_error = err if self.last_error is None else min(err, self.last_error)
        return bool(cfg.target_error and err <= cfg.target_error)

    def _single_view_lights(self, scene: SplatScene, cams: list[PinholeCamera]):
        """Bright splats only one training camera frames (:mod:`.single_view`)."""
        weights = self.y_weights.cpu().numpy()
        level = float(np.median(np.concatenate(
            [(self.data.images[i] @ weights)[::2, ::2].ravel() for i in self.train]))) or 1.0
        area = scene.opacities * np.prod(np.sort(scene.scales, axis=1)[:, 1:], axis=1)
        return single_view_lights(scene.positions, scene.base_colours @ weights, area,
                                  [cams[i] for i in self.train],
                                  [self.data.names[i] for i in self.train], level)

    def _cut_lights(self) -> list[CutLight]:
        """Lights the frame cuts in every view that sees them (:mod:`.frame_edge`), from
        every view (held-out ones too: a photo that frames the light whole is a
        measurement the user took). None unless some view clipped (the white is the
        median of the views' brightest clip floors, as :meth:`FitData.measures_highlights`)."""
        whites = [float(f.max()) for f in (self.data.floor(i)
                                           for i in range(len(self.data.images)))
                  if f is not None]
        if not whites:
            return []
        ratios = white_ratios(self.data.images, float(np.median(whites)),
                              self.y_weights.cpu().numpy())
        return cut_lights(self.data.cameras, ratios, self.data.names)

    def _view_whites(self, views: list[int]) -> np.ndarray | None:
        """Each of ``views``' white, or None when no view clipped: its full-size clip
        floors' median when the views were read from files (:attr:`FitData.peaks`),
        else its fitting-size ones' (:func:`gaslight_usd.sightings.view_whites`); a view
        that clipped nothing gets the median of the others'."""
        floors = [self.data.floor(i) for i in range(len(self.data.images))]
        whites = [float(f.max()) for f in floors if f is not None]
        if not whites:
            return None
        own = view_whites([floors[i] for i in views], float(np.median(whites)))
        if len(self.data.peaks) == len(self.data.images):
            # the full-size peaks are read over the full-size white (a fitting pixel's
            # floor is averaged with the measured pixels it covers: lower)
            full = [p.white for p in self.data.peaks]
            known = [w for w in full if w is not None]
            if known:
                fallback = float(np.median(known))
                own = np.array([fallback if full[i] is None else full[i] for i in views])
        return own

    def _light_seeds(self) -> list[LightSeed]:
        """The compact lights the photos clipped, placed by their outlines
        (:mod:`.light_seeds`) in every view (held-out ones too: the seeds only start
        the fit, and the lights finder reads them); none when no view clipped."""
        if self._seeds is None:
            whites = self._view_whites(list(range(len(self.data.images))))
            self._seeds = [] if whites is None else find_light_seeds(
                self.data.cameras, self.data.light_views(), whites,
                self.y_weights.cpu().numpy())
        return self._seeds

    def _measured_lights(self) -> list[LightSeed]:
        """Where no view clipped (merged brackets, true HDR views), the compact regions
        over :data:`MEASURED_LIGHT_RATIO` x the views' median level, placed by their
        outlines as clipped ones are (:func:`measured_light_seeds`); none where some view
        clipped. They add no initial points (the brightness test's sweep starts measured
        lights well); they keep the plane prior's floater rule off a light in front of a
        wall (:meth:`_assign_planes`) and are drawn fine at the end (:meth:`_fine_power`).
        Not recorded as clipped lights: the lights finder weighs them as the views show."""
        if self._view_whites(list(range(len(self.data.images)))) is not None:
            return []
        if self._measured_seeds is None:
            self._measured_seeds = measured_light_seeds(
                self.data.cameras, self.data.light_views(), self.data.images,
                self.y_weights.cpu().numpy())
        return self._measured_seeds

    def _seeded_lights(self) -> LightSeedPoints:
        """Initial points on :meth:`_light_seeds`, drawn from their own generator (the
        other initial points draw what they drew without seeds)."""
        seeds = self._light_seeds()
        rng = np.random.default_rng([self.seed, 7])
        pts, cols = seed_points(seeds, self.data.cameras, self.data.light_views(),
                                self.data.images, rng, self.y_weights.cpu().numpy())
        return LightSeedPoints(pts, cols, len(seeds),
                               np.array([s.position for s in seeds]).reshape(-1, 3),
                               np.array([s.size for s in seeds]))

    def _light_sightings(self) -> dict[str, Any]:
        """The views' light regions as cones (:func:`gaslight_usd.sightings.sight_lights`),
        from every view (held-out ones too), each over the white its photo clipped at
        (:func:`gaslight_usd.sightings.view_whites`; a view that clipped nothing: the
        median of the views' brightest clip floors, or the views' exposure scale when
        no view clipped)."""
        whites = self._view_whites(list(range(len(self.data.images))))
        if whites is None:
            whites = float(self.data.attributes.get("gaslight:exposure_scale", 1.0) or 1.0)
        return sight_lights(self.data.cameras, self.data.light_views(), whites,
                            self.y_weights.cpu().numpy(),
                            self._measured_views(range(len(self.data.images)))).as_dict()

    def _room_box(self) -> list[dict[str, Any]]:
        """The room's box as the fit's metrics write it (the captured space reads it:
        :func:`gaslight_usd.capture.room_half_spaces`)."""
        return [plane.as_dict() for plane in self.room_planes]

    def _flat_outlines(self) -> list[Outline]:
        """The rectangles the views saw lights in on the room's planes (windows, panels:
        :mod:`gaslight_usd.flat_outlines`), from every view, each side where the views
        that measured it see the light end (:mod:`gaslight_usd.outline_edges`)."""
        if not self.room_planes:
            return []
        floors = [self.data.floor(i) for i in range(len(self.data.images))]
        weights = self.y_weights.cpu().numpy()
        masks = lit_masks(self.data.images, floors, weights)
        outlines = plane_outlines([(p.normal, p.offset) for p in self.room_planes],
                                  self.data.cameras, masks)
        # a pixel at a light's edge is part light: the cells run up to a pixel past it
        return refine_outlines(outlines, self.data.cameras, self.data.images, floors, weights)

    def _redraw_flat_lights(self, scene: SplatScene, backdrop: int, outlines: list[Outline],
                            weighed: list[LightPower]) -> tuple[SplatScene, Redrawn]:
        """Each light the views outlined on a wall or ceiling and one view measured,
        redrawn there as a flat, even emitter (:mod:`gaslight_usd.fit.flat_redraw`: at
        the level the measuring views read, or the power the training views drew where
        lower); the lights as the export's lights finder will see them (the views'
        white, the fit's backdrop, the lights it ``weighed``)."""
        if not self.room_planes or not outlines:
            return scene, Redrawn()
        from ..lights import outlined_lights, search_lights

        probe = scene.subset(np.arange(scene.count))
        probe.metadata["exposure_scale"] = float(
            self.data.attributes.get("gaslight:exposure_scale", 1.0) or 1.0)
        probe.metadata["fit_metrics"] = {"backdrop_splats": backdrop, "clipped_lights":
                                         [light.as_dict() for light in weighed],
                                         "room_box": self._room_box()}
        method = self.data.attributes.get("gaslight:method")
        if not method and all(self.data.floor(i) is None for i in range(len(self.data.images))):
            method = "measured"  # HDR views that clipped nothing: their lights were measured
        probe.metadata["provenance"] = {"hdr_method": method}
        search = search_lights(probe)
        depth = search.space.median_depth()
        planes = [(p.normal, p.offset) for p in self.room_planes]
        compact = outlined_lights(probe.metadata)
        panels = [panel_of(light.position, light.extent, light.axes, planes, depth, outlines,
                           compact) for light in search.lights]
        cams = self.cameras()
        views = [cams[i] for i in self.train]
        images = [self.data.images[i] for i in self.train]
        floors = [self.data.floor(i) for i in self.train]
        weights = self.y_weights.cpu().numpy()
        # a light every view clipped keeps its fitted shape: its power is the uplift's
        # fill, a lower bound (:mod:`.power`), and drawn flat it would only lose more of
        # it near by (docs/measurements.md, session 49)
        pairs, others = [], []
        for panel, light in zip(panels, search.lights, strict=True):
            if panel is not None and panel.outlined and light_sighting(
                    light.position, views, images, floors, weights, search.white) == "measured":
                pairs.append((panel, light.splats))
            else:
                others.append(light.splats)
        # a window the views outlined and one measured, that no light of the finder's
        # holds (its splats smeared off into the room, or taken for the light it throws):
        # the rectangle is its light all the same; one view's outline only where the fit
        # drew its light on the plane (the finder may have grouped it with another light)
        power = np.where(search.emitters & (probe.base_colours.max(axis=1) > search.white),
                         probe.base_colours @ weights, 0.0)
        for outline in outlines:
            panel = outlined_panel(outline, depth)
            if outline.clean and (not outline.single_view or drawn_on_outline(
                    probe.positions, power, outline, depth)) \
                    and not any(np.allclose(panel.centre, p.centre) for p, _ in pairs) \
                    and light_sighting(outline.centre, views, images, floors, weights,
                                       search.white) == "measured":
                pairs.append((panel, np.zeros(0, np.int64)))
        if not pairs:
            return scene, Redrawn()
        scene, redrawn = redraw_flat_lights(
            scene, [p for p, _ in pairs], [i for _, i in pairs], views, search.white, depth,
            weights, tail=backdrop, other_lights=others, images=images, floors=floors,
            ceilings=[self.data.ceiling(i) for i in self.train])
        if redrawn.panels:
            self.progress.message(f"redrew {len(redrawn.panels)} window(s) or panel(s) as "
                                  "flat emitters on their rectangles")
        return scene, redrawn

    def _measured_views(self, views) -> list[bool]:
        """Per view of ``views``: it clipped nothing (its light regions are measured)."""
        floors = [self.data.floor(i) for i in views]
        return [f is None or not bool(np.any(f > 0)) for f in floors]

    def _fine_power(self, scene: SplatScene) -> tuple[SplatScene, list[FinePower]]:
        """The lights the views measured (no view clipped; where some did, the clipped
        compact lights a darker frame measured), brought drawn fine to the power they
        showed the views that measured them, and the floaters that hid them from those
        views left out (:mod:`.fine_power`)."""
        if not self.cfg.fine_power:
            return scene, []
        seeds = self._measured_lights()
        min_views = MIN_VIEWS
        if seeds:
            seed_views = [[i for i in seed.views if i in self.train] for seed in seeds]
        else:  # a clipped set: the compact lights a darker frame measured, matched to it
            seeds, seed_views = self._lights_dark_frames_measured()
            min_views = 1  # the darker frame shot for the light (.fine_power.MIN_VIEWS)
        if not seeds:
            return scene, []
        y = self.y_weights.cpu().numpy()
        bright = self._bright_splats(scene)
        # two frames that measured a light may place its bulb where their lines meet
        scene, seeds, seed_views, bulbs = self._placed_by_frames(scene, seeds, seed_views,
                                                                 bright)
        cams = self.cameras()
        walls = on_planes(scene, self.room_planes)
        own = [bright & (np.linalg.norm(scene.positions - seed.position, axis=1)
                         <= KEEP_OUT_SIZES * seed.size) if bulb is None else bulb
               for seed, bulb in zip(seeds, bulbs, strict=True)]
        claimed = np.sum(own, axis=0)  # how many measured lights hold each splat
        lights = []
        for k, seed in enumerate(seeds):
            rows = np.flatnonzero(own[k])
            # never cleared from in front of a light: the room's walls, and the other
            # measured lights (one may stand on the same sight line)
            others = claimed - own[k] > 0
            views = seed_views[k]
            if not len(rows) or not views:
                continue
            # a light flush with a wall (a ceiling panel) is seen along it: nothing cleared
            keep = (np.ones(scene.count, bool) if on_a_plane(seed.position, 2.0 * seed.size,
                                                             self.room_planes)
                    else walls | others)
            factor, used, cleared = matched_light(scene, rows, seed.position, seed.size,
                                                  [cams[i] for i in views],
                                                  [self.data.images[i] for i in views], y,
                                                  keep=keep, min_views=min_views)
            lights.append(FinePower(seed.position, rows, factor, used, cleared))
        return with_fine_power(scene, lights), lights

    def _close_shaded_sides(self, scene: SplatScene, fine: list[FinePower],
                            rows: list[np.ndarray]) -> tuple[SplatScene, list[ClosedBand]]:
        """The elevations round each light drawn fine (:meth:`_fine_power`; ``rows``: its
        splats in ``scene``) where the frames saw its bulb hidden, closed on the sides no
        photo saw (:mod:`.shade_bands`); lights on a plane of the room's box (panels,
        windows) left as they are."""
        lights = [own for light, own in zip(fine, rows, strict=True)
                  if len(own) and not on_a_plane(light.position, 0.05 * self.extent,
                                                 self.room_planes)]
        if not lights:
            return scene, []
        cams = self.cameras()
        up = np.mean([-cams[i].R[1] for i in self.train], axis=0)
        vertical = box_vertical(self.room_planes, up)
        if vertical is None:
            vertical = room_vertical(np.asarray(self._init_model().points, np.float64), up,
                                     np.random.default_rng([self.seed, 13]))
        return close_hidden_bands(scene, lights, self._bright_splats(scene),
                                  [cams[i] for i in self.train],
                                  [self.data.images[i] for i in self.train],
                                  [self.data.floor(i) for i in self.train],
                                  self.y_weights.cpu().numpy(), vertical)

    def _bright_splats(self, scene: SplatScene) -> np.ndarray:
        """(N,) splats brighter than a measured light must be
        (:data:`MEASURED_LIGHT_RATIO` x the views' median level)."""
        y = self.y_weights.cpu().numpy()
        return scene.base_colours @ y > MEASURED_LIGHT_RATIO * measured_level(
            self.data.images, y)

    def _bulbs_to_frames_midway(self) -> None:
        """Move the bulbs two darker frames measured where their sight lines meet while
        the fit still has steps to go (:meth:`_placed_by_frames`): moved at the end, the
        room round them was fitted to a bulb drawn elsewhere (a shade's side fitted
        see-through where the bulb was drawn under it)."""
        if not self.cfg.fine_power:
            return
        seeds = self._measured_lights()
        if seeds:
            seed_views = [[i for i in seed.views if i in self.train] for seed in seeds]
        else:
            seeds, seed_views = self._lights_dark_frames_measured()
        if not seeds:
            return
        scene = self.model.to_scene(self.active_degree(), {})
        moved, _, _, _ = self._placed_by_frames(scene, seeds, seed_views,
                                                self._bright_splats(scene),
                                                record=False)
        rows = np.flatnonzero(np.any(moved.positions != scene.positions, axis=1))
        if not len(rows):
            return
        self.model.set_rows(torch.as_tensor(rows, device=self.device), {
            "means": torch.as_tensor(moved.positions[rows], device=self.device)})
        if self.planes is not None:  # the moved splats' planes are where they are now
            self._assign_planes()

    def _placed_by_frames(self, scene: SplatScene, seeds: list[LightSeed],
                          seed_views: list[list[int]], bright: np.ndarray,
                          record: bool = True
                          ) -> tuple[SplatScene, list[LightSeed], list[list[int]],
                                     list[np.ndarray | None]]:
        """Each light two or more darker frames measured, its bulb moved where their
        sight lines meet (:mod:`.frames_meet`), one frame measured, where its line passes
        the seed (:func:`.frames_meet.frame_and_seed`); its seed put there at the radius
        they measured and its views made those frames (to be matched to them); the
        others as they were. Where no view clipped, every view that framed a light
        measured it: only a light some views read far dimmer than others (a shaded
        bulb's glow) is placed, by the views that read it brightest
        (:func:`.frames_meet.bulb_sightings`). The last list
        holds, for each light so placed, its bulb's splats ((N,) mask): only those are
        the light; the rest the seed held (the glow the photos saw at a shade's
        opening) may be cleared from in front of it, as the frames saw through it."""
        bulbs: list[np.ndarray | None] = [None] * len(seeds)
        training = self._training_views()
        unclipped = training is None
        y = self.y_weights.cpu().numpy()
        if unclipped:  # a light measures where it reads over what a measured light must
            cams = self.cameras()
            training = (MEASURED_LIGHT_RATIO * measured_level(self.data.images, y)
                        / WHITE_MULTIPLE, [cams[i] for i in self.train],
                        [self.data.images[i] for i in self.train], [None] * len(self.train))
        white, views, images, floors = training
        seeds, seed_views = list(seeds), list(seed_views)
        for k, seed in enumerate(seeds):
            sightings = measuring_sightings(seed.position, seed.size, views, images, floors,
                                            y, white)
            if unclipped:
                bulb_seen = bulb_sightings(sightings)
                if len(bulb_seen) == len(sightings):
                    continue  # all read it alike: nothing tells a bulb from its glow
                sightings = bulb_seen
            meeting = frames_meeting(sightings)
            if meeting is None and not unclipped and not on_a_plane(
                    seed.position, 2.0 * seed.size, self.room_planes):
                # one frame and the seed; not a light flush with a wall or the ceiling (a
                # panel: its splats are its rectangle, not a bulb's ball)
                meeting = frame_and_seed(sightings, seed.position, seed.size)
            if meeting is None:
                continue
            rows = np.flatnonzero(bright & (np.linalg.norm(
                scene.positions - seed.position, axis=1) <= KEEP_OUT_SIZES * seed.size))
            scene, meeting, bulb = moved_to_meeting(scene, rows, meeting, y)
            if not len(bulb):
                continue
            if record:
                self.frames_met.append(meeting.as_dict())
            mask = np.zeros(scene.count, bool)
            mask[bulb] = True
            bulbs[k] = mask
            seeds[k] = replace(seed, position=meeting.position, size=meeting.radius)
            seed_views[k] = [self.train[i] for i in meeting.views]
        return scene, seeds, seed_views, bulbs

    def _training_views(self) -> tuple[float, list[PinholeCamera], list[np.ndarray],
                                       list[np.ndarray | None]] | None:
        """The training views' median white, cameras, images and clip floors; None where
        no view has a white (nothing clipped)."""
        whites = self._view_whites(self.train)
        if whites is None:
            return None
        cams = self.cameras()
        return (float(np.median(whites)), [cams[i] for i in self.train],
                [self.data.images[i] for i in self.train],
                [self.data.floor(i) for i in self.train])

    def _lights_dark_frames_measured(self) -> tuple[list[LightSeed], list[list[int]]]:
        """The compact lights the photos clipped (:meth:`_light_seeds`) that a training
        view measured unclipped (a darker frame shot for them:
        :func:`.fine_power.measuring_views`), and those views. The fit matched such a
        light to that frame only at the fitting size, and the other views' clipped pixels
        (bounds, with the uplift's fill pulling weakly) left it free to overshoot or fall
        short of it (``gaslight2usd bench --suite chain --method "recursive + extra dark
        frames"``; docs/measurements.md, session 56)."""
        training = self._training_views()
        if training is None:
            return [], []
        white, views, images, floors = training
        y = self.y_weights.cpu().numpy()
        seeds, seed_views = [], []
        for seed in self._light_seeds():
            measuring = measuring_views(seed.position, seed.size, views, images, floors, y,
                                        white)
            if measuring:
                seeds.append(seed)
                seed_views.append([self.train[i] for i in measuring])
        return seeds, seed_views

    def _fill_holes(self) -> None:
        """Splats on the training views' patches that no splat covers (:mod:`.holes`):
        densification never reaches them. Run once, at the end of the densify window
        (:meth:`_floaters_step`)."""
        clipped = [np.zeros(self.data.images[i].shape[:2], bool)
                   if self.data.floor(i) is None else self.data.floor(i) > 0
                   for i in self.train]
        if not any(mask.any() for mask in clipped):
            return  # nothing clipped (true HDR, merged brackets): no patch to seed
        degree = self.active_degree()
        cams = [self.data.cameras[i] for i in self.train]
        with torch.no_grad():
            alphas = [render(self.model.params(degree), cam, background=0.0,
                             sh_degree=degree).alpha.cpu().numpy() for cam in cams]
        scene = self.model.to_scene(degree, {})
        holes = fill_holes(scene, cams, alphas, [self.data.images[i] for i in self.train],
                           [self.data.names[i] for i in self.train],
                           self.y_weights.cpu().numpy(), self.mean_level,
                           np.random.default_rng([self.seed, 13]), clipped,
                           white=self._plane_white or 0.0, planes=self.room_planes)
        cap = self.cfg.budget - self._backdrop_reserve()
        take = min(holes.count, int(HOLES_SHARE * cap))
        self.holes_filled = {"splats": take, "freed": 0, "empty_pixels": holes.empty_pixels}
        if not take:
            return
        self.holes_filled["freed"] = self._make_room(take - max(cap - self.model.count, 0))
        pick = np.sort(np.random.default_rng([self.seed, 14]).choice(holes.count, take,
                                                                      replace=False))
        self.model.add(holes.positions[pick], holes.colours[pick], holes.sizes[pick],
                       self.cfg.init_opacity)
        if self.planes is not None:  # new splats, new indices
            self._assign_planes()
        self._reset_stats()
        self.progress.message(f"step {self.step}: {take} splats on the views' empty patches")

    def _make_room(self, count: int) -> int:
        """Prune the ``count`` splats that contribute least to the training views
        (:meth:`_contribution_scores`); returns how many went."""
        if count <= 0:
            return 0
        score = self._contribution_scores()
        drop = torch.zeros(self.model.count, dtype=torch.bool, device=score.device)
        drop[torch.argsort(score)[:count]] = True
        self.model.prune(drop)
        return int(count)

    def _floaters_step(self) -> int:
        """The step after which the lights drawn just in front of a camera are moved onto
        the room's surfaces (:meth:`_surface_floaters`): the end of the densify window."""
        return max(int(self.cfg.densify_until * self.cfg.iterations), 1)

    def _surface_floaters(self) -> None:
        """Move the lights one photo drew just in front of its camera onto the room's
        surfaces while the fit still has steps to go.

        Hidden behind such a floater, whatever lies between that camera and the light
        was fitted blind: dim fog splats the photo never had to see through. Moved at the
        end, the light lands behind them (``panels:7``'s ceiling panel from its true HDR
        views: two thirds of its light lost in its own photo); moved here, the remaining steps
        clear the photo's view of it again. The other rules run at the end
        (:meth:`_finish`), where the lights they place are recorded."""
        scene = self.model.to_scene(self.active_degree(), {})
        moved, surfaced = self._surface_sunk_lights(scene, rules=frozenset({"near"}))
        rows = np.flatnonzero(np.any(moved.positions != scene.positions, axis=1))
        if not len(rows):
            return
        self.floaters_moved += len(rows)
        index = torch.as_tensor(rows, device=self.device)
        self.model.set_rows(index, {
            "means": torch.as_tensor(moved.positions[rows], device=self.device),
            "log_scales": torch.as_tensor(moved.log_scales[rows], device=self.device)})
        if self.planes is not None:  # the moved splats' planes are where they are now
            self._assign_planes()

    def _surface_sunk_lights(self, scene: SplatScene, rules: frozenset[str] | None = None,
                             broad_on_planes: bool = False
                             ) -> tuple[SplatScene, SurfacedLights]:
        """Compact lights one photo frames sunk behind a surface, broad lights off their
        wall, and lights one photo drew just in front of its camera, moved onto the
        room's boundary (:mod:`.sunk_lights`; ``rules``: which of them, all by default;
        ``broad_on_planes``: broad lights onto the room's planes where those are the
        boundary).
        Where no view clipped (merged brackets, true HDR views) broad lights stay: the
        photos' light regions over their white say which splats are lights, and without a
        clip level a lit wall round a window is as bright as the window."""
        if not self.cfg.clip_bounds:
            return scene, SurfacedLights(0, 0.0, 0.0, 0)
        weights = self.y_weights.cpu().numpy()
        rules = RULES if rules is None else rules
        whites = self._view_whites(self.train)
        if whites is None:
            rules = rules - {"broad"}
            if not rules:
                return scene, SurfacedLights(0, 0.0, 0.0, 0)
            # the lights are what the single-view check calls bright: "over the white"
            # means "clipped" to the broad rule, which needs a photo's clip level
            level = float(np.median([np.median(self.data.images[i] @ weights)
                                     for i in self.train]))
            whites = np.full(len(self.train), BRIGHT_RATIO * level)
        cams = self.cameras()
        views = [cams[i] for i in self.train]
        photos = [self.data.light_views()[i] for i in self.train]
        sightings = sight_lights(views, photos, whites, weights, self._measured_views(self.train))
        scene, surfaced = surface_sunk_lights(scene, views, photos, whites, weights, sightings,
                                              rules=rules, planes=self.room_planes,
                                              broad_on_planes=broad_on_planes)
        for light in surfaced.placed:  # indices among the training views -> all views
            light.views = [self.train[v] for v in light.views]
        if surfaced.moved:
            self.progress.message(f"moved {surfaced.moved} light splat(s) off the room's "
                                  "surfaces back onto them")
        return scene, surfaced

    def _weigh_clipped_lights(self, scene: SplatScene, backdrop: int,
                              floors: list[np.ndarray | None]
                              ) -> tuple[SplatScene, list[LightPower]]:
        """The clipped compact lights' power from the surfaces they light
        (:mod:`.power`), judged on the training views; every light the finder keeps is
        listed with where its power came from."""
        cams = self.cameras()
        views = [cams[i] for i in self.train]
        images = [self.data.images[i] for i in self.train]
        weights = self.y_weights.cpu().numpy()
        probe = scene.subset(np.arange(scene.count))
        # as the export's lights finder will see it: the views' white, the fit's backdrop
        probe.metadata["exposure_scale"] = float(
            self.data.attributes.get("gaslight:exposure_scale", 1.0) or 1.0)
        probe.metadata["fit_metrics"] = {"backdrop_splats": backdrop,
                                         "room_box": self._room_box()}
        weigh, keep, surfaces, opaque = lights_to_weigh(probe, views, images, floors, weights)
        if weigh:
            self.progress.message(f"weighing {len(weigh)} clipped light(s) by the surfaces "
                                  "they light")
            scene = infer_light_power(scene, weigh, views, images, floors, weights, surfaces,
                                      opaque, self.extent, seed=self.seed)
        return scene, weigh + keep

    def _pose_agreement(self) -> dict[str, Any] | None:
        """How the given poses agree with the photos (:mod:`gaslight_usd.poses.agreement`):
        the triangulation's matches, else the model's own observations; None when
        neither exists (the splats bend to wrong poses silently, so say it here)."""
        agreement = pose_agreement(self._init_model())
        if agreement is None and self._init_model() is not self.data.model:
            agreement = pose_agreement(self.data.model)
        return agreement.as_dict() if agreement is not None else None

    def _finish(self, t0: float, stop_reason: str, resumed: bool,
                init_seconds: float) -> FitResult:
        """Prune idle splats, choose the SH degree, add the backdrop and the clipped
        lights' power, score the result and save the last checkpoint."""
        cfg = self.cfg
        pruned = self._prune_idle()
        degree, scores = self._choose_degree()
        scene = self.model.to_scene(degree, {})
        scene, sheets = self._squash_onto_planes(scene)
        scene, surfaced = self._surface_sunk_lights(scene)
        before = scene.count
        scene, fine = self._fine_power(scene)
        scene, shaded = self._close_shaded_sides(scene, fine, rows_after(fine, before))
        cams = self.cameras()
        backdrop = unseen_backdrop(scene, [cams[i] for i in self.train],
                                   cfg.backdrop_tiles, room=cfg.budget - scene.count,
                                   y_weights=self.y_weights.cpu().numpy())
        if backdrop.count:
            scene = concatenate(scene, backdrop)
        outlines = self._flat_outlines()
        # where the photos were taken and where they saw light over the white: the
        # captured space, the default probe and the lights finder start there
        scene.metadata = {**scene.metadata,
                          "cameras": {"centres": [[round(float(v), 6) for v in c.center]
                                                  for c in self.data.cameras]},
                          "light_sightings": self._light_sightings(),
                          "light_seeds": [seed.as_dict() for seed in self._light_seeds()]
                          + [light.as_dict() for light in surfaced.placed],
                          "flat_outlines": [o.as_dict() for o in outlines]}
        lights: list[LightPower] = []
        train_floors = [self.data.floor(i) for i in self.train]
        if cfg.clip_bounds and cfg.infer_power and any(f is not None for f in train_floors):
            scene, lights = self._weigh_clipped_lights(scene, backdrop.count, train_floors)
        # broad lights (windows) left a few centimetres off their wall, onto its plane:
        # after the weighing, which gathers the rest of the room's light from the fit as
        # its views left it (moved first, the window's light on the surfaces moved the
        # lamps' factors: docs/measurements.md, session 35)
        on_walls = SurfacedLights(0, 0.0, 0.0, 0)
        if self.room_planes:
            scene, on_walls = self._surface_sunk_lights(scene, frozenset({"broad"}),
                                                        broad_on_planes=True)
        redrawn = Redrawn()
        if cfg.redraw_flat_lights:
            scene, redrawn = self._redraw_flat_lights(scene, backdrop.count, outlines, lights)
        scene, oversized = self._cut_oversized(scene, backdrop.count)
        scene, at_cameras = self._drop_camera_floaters(scene, backdrop.count)
        if (sheets or shaded or backdrop.count or lights or surfaced.moved or on_walls.moved
                or oversized["splats"] or redrawn.panels or at_cameras["splats"]) and self.held:
            scores = self._evaluate_scene(scene, self.held)
        seconds = time.perf_counter() - t0
        metrics = {
            "splats": scene.count,
            "backdrop_splats": backdrop.count,
            "held_out_views": [self.data.names[i] for i in self.held],
            "held_out_log_lum_rmse_stops": scores["log_lum_rmse_stops"],
            "held_out_pu21_psnr": scores["pu21_psnr"],
            "sh_degree": degree,
            "iterations": self.step,
            "stop_reason": stop_reason,
            "pruned_idle": pruned,
            "oversized_cut": oversized,
            "camera_floaters_dropped": at_cameras,
            "init": self.init_method,
            "planes": self.planes.as_dict() if self.planes is not None else None,
            "room_box": self._room_box(),
            "lit_floor": self.lit_floor_info,
            "fit_seconds": round(seconds, 2),
            "init_seconds": round(init_seconds, 2),
            "resumed": resumed,
            "clipped_lights": [light.as_dict() for light in lights],
            "fine_power": [light.as_dict() for light in fine],
            "placed_by_frames": self.frames_met,
            "surfaced_lights": {**surfaced.as_dict(), "floaters_moved_midway":
                                self.floaters_moved},
            "broad_lights_on_walls": on_walls.as_dict(),
            "flat_lights_redrawn": redrawn.as_dict(),
            "fog_dropped": self.fog_dropped,
            "squashed_onto_planes": sheets,
            "shaded_sides_closed": [band.as_dict() for band in shaded],
            "holes_filled": self.holes_filled,
            "single_view_lights": [light.as_dict() for light in self._single_view_lights(
                scene.subset(np.arange(scene.count - backdrop.count)), cams)],
            "exposure_outliers": exposure_outliers(
                self._init_model(), self.data.cameras, self.data.images, self.data.names,
                [self.data.floor(i) for i in range(len(self.data.images))],
                self.y_weights.cpu().numpy()),
            "pose_agreement": self._pose_agreement(),
            "cut_lights": [light.as_dict() for light in self._cut_lights()],
        }
        if self.refiner is not None:
            metrics["pose_refinement"] = self.refiner.summary(
                [self.data.cameras[i] for i in self.train])
        if not self.held:
            metrics["note"] = "no held-out views (too few views): errors are on training views"
        if self.checkpoint is not None:
            self.elapsed = seconds
            save_checkpoint(self.checkpoint, self._state())
        return FitResult(scene=scene, metrics=metrics, history=self.history, cameras=cams)


def fit_splats(data: FitData, config: FitConfig, seed: int = 0,
               progress: Progress | None = None, checkpoint: Path | None = None,
               resume: bool = False, device: str = "cpu", threads: int | None = None
               ) -> FitResult:
    """Fit splats to ``data``; see the module docstring for what stops it.

    ``threads``: torch CPU threads during the fit (default: cores - 1, at least 1).
    ``device``: ``cpu`` (compiled kernels; deterministic for a seed) or ``cuda``
    (the torch renderer on the GPU: the same fit, but sums in another order,
    so its splats differ from the CPU's as another seed's would; two GPU runs
    of a seed on one H100 repeated exactly).
    """
    dev = resolve_device(device)
    # OpenMP threads spin-wait: on a small shared machine one thread per spare
    # core is much faster than oversubscribing (measured 2-20x on 2 cores).
    # The caller's setting is restored afterwards.
    before = torch.get_num_threads()
    torch.set_num_threads(threads or max(1, (os.cpu_count() or 2) - 1))
    try:
        # whatever the caller's grad mode (a torch.no_grad block, or one a Ctrl-C cut
        # short, which leaves it off), the fit needs its gradients
        with torch.enable_grad():
            return Trainer(data, config, seed, progress, checkpoint, dev).run(resume=resume)
    finally:
        torch.set_num_threads(before)
