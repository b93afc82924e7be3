"""Exposure brackets: merge accuracy on real HDR truth, response, alignment, grouping."""

from __future__ import annotations

import json
import math
from datetime import datetime
from pathlib import Path

import numpy as np
import pytest
from conftest import TEST_HDRI, run_cli, write_jpeg

from gaslight_usd.errors import InputError
from gaslight_usd.imageio import read_image
from gaslight_usd.poses.views import load_views
from gaslight_usd.uplift import GAMMA22, SRGB
from gaslight_usd.uplift.bracket import (
    Bracket,
    apply_shift,
    check_bracket,
    estimate_shifts,
    group_by_exif,
    merge_bracket,
    read_group_file,
    recover_response,
)


def real_truth(width: int = 192, height: int = 128, index: int = 3) -> np.ndarray:
    """A perspective crop of an unclipped real panorama (bundled), aimed at its light."""
    from gaslight_usd.evaluation.reference import load_source, make_pair

    pair = make_pair(load_source(TEST_HDRI / "forest.exr"), index, seed=11, width=width,
                     height=height, aim_light_fraction=1.0)
    return pair.truth


def make_bracket(truth: np.ndarray, evs: list[float], curve=SRGB) -> list[np.ndarray]:
    return [np.round(curve.to_encoded(np.clip(truth * 2.0 ** e, 0, 1)) * 255) / 255
            for e in evs]


def stop_errors(pred: np.ndarray, truth: np.ndarray, evs: list[float]) -> np.ndarray:
    """|log2 error| of luminance where some exposure saw the pixel (not clipped, not dark)."""
    lum_t, lum_p = truth.mean(-1), pred.mean(-1)
    seen = (lum_t * 2.0 ** max(evs) > 0.01) & (lum_t * 2.0 ** min(evs) < 0.9)
    return np.abs(np.log2(np.maximum(lum_p[seen], 1e-9) / lum_t[seen]))


def test_bracket_merge_recovers_real_radiance_within_a_tenth_of_a_stop():
    truth = real_truth()
    evs = [-6.0, -4.0, -2.0, 0.0, 2.0]
    stack = make_bracket(truth, evs)
    res = merge_bracket(stack, evs, SRGB, align=False)
    assert res.reference == 2  # the middle exposure
    pred = res.linear / 2.0 ** evs[res.reference]  # back to the truth's scale
    err = stop_errors(pred, truth, evs)
    assert np.median(err) < 0.1
    assert np.percentile(err, 95) < 0.3


def test_debevec_response_recovers_the_curve_and_the_radiance():
    truth = real_truth(index=5)
    evs = [-4.0, -2.0, 0.0, 2.0]
    stack = make_bracket(truth, evs, GAMMA22)
    curve = recover_response(stack, evs)
    v = np.linspace(0.2, 0.9, 8, dtype=np.float32)
    np.testing.assert_allclose(np.log2(curve.to_linear(v)), np.log2(GAMMA22.to_linear(v)),
                               atol=0.15)
    res = merge_bracket(stack, evs, curve, align=False)
    err = stop_errors(res.linear / 2.0 ** evs[res.reference], truth, evs)
    assert np.median(err) < 0.15


def test_hand_held_shifts_are_found_and_compensated():
    truth = real_truth(width=256, height=192, index=2)
    evs = [-2.0, 0.0, 2.0]
    stack = make_bracket(truth, evs)
    moved = [apply_shift(stack[0], (2.0, -3.0)), stack[1], apply_shift(stack[2], (-1.5, 1.0))]
    shifts = estimate_shifts(moved, evs, SRGB)
    np.testing.assert_allclose(shifts[0], (-2.0, 3.0), atol=0.35)
    np.testing.assert_allclose(shifts[1], (0.0, 0.0), atol=1e-9)
    np.testing.assert_allclose(shifts[2], (1.5, -1.0), atol=0.35)
    aligned = merge_bracket(moved, evs, SRGB).linear
    unaligned = merge_bracket(moved, evs, SRGB, align=False).linear
    inner = (slice(8, -8), slice(8, -8))
    err = lambda a: np.median(stop_errors(a[inner], truth[inner], evs))  # noqa: E731
    assert err(aligned) < 0.5 * err(unaligned)


def write_bracket_folder(folder: Path, truth: np.ndarray, times: list[float],
                         prefix: str = "b") -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, t in enumerate(times):
        enc = SRGB.to_encoded(np.clip(truth * t * 100, 0, 1))
        paths.append(write_jpeg(folder / f"{prefix}{i}.jpg",
                                np.round(enc * 255).astype(np.uint8), exposure_time=t,
                                f_number=1.0))
    return paths


def scene(h: int = 48, w: int = 64, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    base = 0.05 + 0.4 * (x / w) + 0.1 * rng.random((h, w)).astype(np.float32)
    base[10:16, 40:50] = 3.0  # a window above white at the middle exposures
    return np.repeat(base[..., None], 3, axis=2)


def test_grouping_by_exif_and_content(tmp_path):
    a = write_bracket_folder(tmp_path / "p", scene(seed=1), [0.0025, 0.01, 0.04], "a")
    b = write_bracket_folder(tmp_path / "p", scene(seed=2)[:, ::-1], [0.0025, 0.01], "b")
    write_bracket_folder(tmp_path / "p", scene(seed=3)[::-1], [0.01], "c")
    views = load_views(tmp_path / "p", "srgb_tx", "lin_rec709")
    groups = group_by_exif(views)
    assert [[v.path for v in g.views] for g in groups] == [a, b, [tmp_path / "p" / "c0.jpg"]]
    assert [g.is_bracket for g in groups] == [True, True, False]


def test_photos_of_different_views_are_not_a_bracket(photo_folder):
    """Three different random pictures with different exposures: no bracket."""
    views = load_views(photo_folder, "srgb_tx", "lin_rec709")
    assert not any(g.is_bracket for g in group_by_exif(views))


def test_bad_brackets_get_clear_messages(tmp_path):
    write_bracket_folder(tmp_path / "p", scene(), [0.01, 0.01], "same")
    views = load_views(tmp_path / "p", "srgb_tx", "lin_rec709")
    with pytest.raises(InputError, match="single exposure"):
        check_bracket(Bracket("same", views))
    small = write_bracket_folder(tmp_path / "q", scene(h=32, w=40), [0.04], "small")
    mixed = load_views([*sorted((tmp_path / "p").glob("*.jpg"))[:1], *small], "srgb_tx",
                       "lin_rec709")
    with pytest.raises(InputError, match="mixes image sizes"):
        check_bracket(Bracket("mixed", mixed))
    bad = tmp_path / "groups.txt"
    bad.write_text("view one.jpg two.jpg\n")
    with pytest.raises(InputError, match="line 1"):
        read_group_file(bad)


def test_cli_auto_merges_brackets_and_refuses_single_exposures(tmp_path):
    truth = scene()
    write_bracket_folder(tmp_path / "p", truth, [0.0025, 0.01, 0.04, 0.16], "view")
    out = tmp_path / "hdr"
    r = run_cli("hdr", str(tmp_path / "p"), "-o", str(out), "--json", "-q",
                "--working-space", "lin_rec709")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["brackets"] == 1
    (exr,) = sorted(out.glob("*.exr"))
    img = read_image(exr)
    assert img.metadata["gaslight:method"] == "bracket"
    # relative radiance: 1.0 = white at the set's median EXIF exposure
    ref_t = 2.0 ** img.metadata["gaslight:reference_ev"]
    expected = truth * 100 * ref_t
    window = (slice(11, 15), slice(41, 49))
    ratio = img.pixels[window].mean() / expected[window].mean()
    assert abs(np.log2(ratio)) < 0.1  # the window, 6x above white, is recovered

    single = tmp_path / "single"
    write_bracket_folder(single, scene(seed=4), [0.01], "only")
    r = run_cli("hdr", str(single), "-o", str(tmp_path / "x"), "--method", "bracket")
    assert r.returncode in (2, 3) and "no exposure brackets" in r.stderr
    groups = tmp_path / "groups.json"
    groups.write_text(json.dumps({"v": ["only0.jpg"]}))
    r = run_cli("hdr", str(single), "-o", str(tmp_path / "y"), "--group-file", str(groups))
    assert r.returncode in (2, 3) and "no exposure brackets" in r.stderr


def test_neighbouring_views_of_a_smooth_ceiling_are_not_a_bracket():
    """The example's ceiling views: same size, no capture time, 1/3 EV apart by auto-exposure
    and alike at 48 px (correlation up to 0.70) -- still separate views, no brackets."""
    from gaslight_usd.locate import example_room
    from gaslight_usd.uplift.bracket import find_brackets

    photos = sorted((example_room() / "photos").glob("*.jpg"))
    if not photos:
        pytest.skip("the bundled example examples/room is missing: it ships with the "
                    "project (git checkout examples/room, or set GASLIGHT_EXAMPLE)")
    assert find_brackets(photos, "sRGB - Texture", "ACEScg") == []


# -- brackets grouped the way photographers shoot them (issue 22) ---------------

def _room_scenes() -> list[np.ndarray]:
    from gaslight_usd.evaluation.bracket_shoot import room_scenes
    from gaslight_usd.locate import example_room

    if not (example_room() / "truth" / "view_21.exr").exists():
        pytest.skip("the bundled example's truth views are not here")
    return room_scenes([0, 6, 9, 15, 21, 3, 12])


def _panorama_scenes() -> list[np.ndarray]:
    from gaslight_usd.evaluation.bracket_shoot import panorama_scenes

    return panorama_scenes(7, folder=TEST_HDRI)


SCENES = {"room": _room_scenes, "panoramas": _panorama_scenes}


def _frame_stats(pos) -> tuple[float, float]:
    """(clipped fraction of the brightest frame, median encoded level of the darkest)."""
    by_time = sorted(pos.frames, key=lambda f: f.true_time)
    bright = read_image(by_time[-1].path).pixels.max(axis=-1)
    dark = read_image(by_time[0].path).pixels.max(axis=-1)
    return float(np.mean(bright >= 0.99)), float(np.median(dark))


@pytest.mark.parametrize("source", SCENES)
def test_aeb_folder_gives_one_hdr_view_per_position(tmp_path, source):
    """Five positions shot as AEB brackets (0/-2/+2 three times, -4..+4, 0/-3/+3/-6/+6),
    hand-held, brightest frames >= 60 % clipped, singles between, all in one folder:
    one HDR view per position (the old grouping made 12 views of these 21 photos)."""
    from gaslight_usd.evaluation.bracket_shoot import aeb_shoot

    scenes = SCENES[source]()
    shoot = aeb_shoot(scenes[:5], tmp_path / "photos", scenes[5:7])
    stats = [_frame_stats(p) for p in shoot.positions]
    assert all(clipped >= 0.6 for clipped, _ in stats), stats
    assert min(dark for _, dark in stats) < 0.05, stats  # a nearly black darkest frame
    out = tmp_path / "hdr"
    r = run_cli("hdr", str(tmp_path / "photos"), "-o", str(out), "--method", "bracket",
                "--working-space", "lin_rec709", "--json", "-q")
    assert r.returncode == 0, r.stderr
    result = json.loads(r.stdout)
    groups = [v["photos"] for v in result["grouping"]["views"]]
    expected = [[p.name for p in pos.photos] for pos in shoot.positions]
    expected += [[p.name for p in s.photos] for s in shoot.singles]
    assert sorted(groups) == sorted(expected)
    assert result["views"] == 7 and result["brackets"] == 5
    report = json.loads((out / "report.json").read_text())
    assert report["stages"][0]["metadata"]["grouping"] == result["grouping"]
    (warning,) = result["grouping"]["warnings"]  # the lone frame shot right after bracket 2
    assert warning.startswith(f"{shoot.singles[0].photos[0].name} is left as a view of its own")
    assert "differs" in warning
    exrs = {read_image(p).metadata["gaslight:bracket"]: p for p in out.glob("*.exr")}
    assert len(exrs) == 7
    for pos in shoot.positions:
        img = read_image(exrs[",".join(p.name for p in pos.photos)])
        assert img.metadata["gaslight:grouped_by"].endswith("image similarity")
        truth = pos.expected(img.metadata["gaslight:reference_ev"]).mean(axis=-1)
        seen = pos.seen()
        seen[:4], seen[-4:], seen[:, :4], seen[:, -4:] = False, False, False, False
        err = np.abs(np.log2(np.maximum(img.pixels.mean(axis=-1), 1e-9) / truth))[seen]
        assert np.median(err) < 0.1, (pos.name, np.median(err))


def test_without_capture_times_file_order_groups_the_same(tmp_path):
    from gaslight_usd.evaluation.bracket_shoot import aeb_shoot
    from gaslight_usd.uplift.bracket import group_views

    scenes = _room_scenes()
    shoot = aeb_shoot(scenes[:5], tmp_path / "p", scenes[5:7], capture_time=False)
    grouping = group_views(load_views(tmp_path / "p", "srgb_tx", "lin_rec709"))
    assert grouping.order.startswith("file name")
    got = [[v.path for v in b.views] for b in grouping.brackets if b.is_bracket]
    assert got == [pos.photos for pos in shoot.positions]


def _photo(name: str, ev: float | None, taken: float | None = None):
    from gaslight_usd.uplift.grouping import Photo

    return Photo(name, Path(f"{name}.jpg"), ev, None if ev is None else 2.0 ** ev,
                 (4, 6, 3), taken)


def _groups(photos, similar=None) -> list[list[str]]:
    from gaslight_usd.uplift.grouping import plan_groups

    return [[photos[i].name for i in b.views] for b in plan_groups(photos, similar).brackets]


def test_capture_time_orders_frames_not_file_names():
    """Two cards' numbering interleaves the names; the capture times tell the brackets."""
    evs = [-7, -9, -5]
    photos = ([_photo(f"b{k}", e, 100.0 + 0.3 * k) for k, e in enumerate(evs)]
              + [_photo(f"a{k}", e, 110.0 + 0.3 * k) for k, e in enumerate(evs)])
    assert _groups(photos) == [["b0", "b1", "b2"], ["a0", "a1", "a2"]]
    untimed = [_photo(p.name, p.ev) for p in photos]  # file order: a0 a1 a2 b0 b1 b2
    assert _groups(untimed) == [["a0", "a1", "a2"], ["b0", "b1", "b2"]]


def test_back_to_back_brackets_stay_apart_and_steps_must_be_constant():
    cam = [0, -2, 2, 0, -2, 2]  # the camera's order, two brackets 0.3 s apart
    photos = [_photo(f"p{k}", e - 7, 0.3 * k) for k, e in enumerate(cam)]
    assert _groups(photos) == [["p0", "p1", "p2"], ["p3", "p4", "p5"]]
    # auto-exposure drifting by uneven steps is no bracket; a late frame (5 s) is alone
    drift = [_photo("d0", -7.0, 0), _photo("d1", -6.0, 0.5), _photo("d2", -3.5, 1.0),
             _photo("d3", -5.0, 6.5)]
    assert _groups(drift) == [["d0", "d1"], ["d2"], ["d3"]]
    # rounded shutter labels (1/500, 1/125, 1/30: 2.0 and 2.06 stops) are one step
    labels = [_photo(f"s{k}", math.log2(t), 0.2 * k) for k, t in
              enumerate([1 / 125, 1 / 500, 1 / 30])]
    assert _groups(labels) == [["s0", "s1", "s2"]]


def test_similarity_confirms_and_a_pair_with_nothing_to_compare_needs_company():
    photos = [_photo(f"p{k}", e - 7, 0.3 * k) for k, e in enumerate([0, -2, 2, 4])]
    sims = {frozenset({1, 0}): None, frozenset({0, 2}): 0.95, frozenset({2, 3}): 0.3}
    similar = lambda i, j: sims.get(frozenset({i, j}))  # noqa: E731
    # the nearly black p1 joins (nothing to compare), p3 of another view does not
    assert _groups(photos, similar) == [["p0", "p1", "p2"], ["p3"]]
    from gaslight_usd.uplift.grouping import plan_groups

    grouping = plan_groups(photos, similar)
    assert grouping.brackets[0].similarity == [None, 0.95]
    (warning,) = grouping.warnings
    assert warning.startswith("p3.jpg is left as a view of its own") and "0.30" in warning
    # a pair that nothing confirms is no bracket
    assert _groups(photos[:2], lambda i, j: None) == [["p0"], ["p1"]]


def test_capture_time_reads_subseconds(tmp_path):
    import OpenImageIO as oiio

    from gaslight_usd.evaluation.bracket_shoot import write_photo
    from gaslight_usd.imageio import read_header
    from gaslight_usd.uplift.grouping import capture_time, read_photo

    when = datetime(2026, 11, 24, 10, 0, 1, 250000)
    path = write_photo(tmp_path / "x.jpg", np.full((8, 8, 3), 0.5, np.float32), 1 / 60, when)
    assert capture_time(read_header(path)) == pytest.approx(when.timestamp(), abs=1e-6)
    photo = read_photo(path)
    assert photo.exposure_time == pytest.approx(1 / 60, rel=1e-3)
    assert photo.ev == pytest.approx(math.log2(1 / 60 / 64), abs=1e-3)  # f/8, ISO 100
    assert oiio.ImageInput.open(str(path)).spec().getattribute(
        "Exif:SubsecTimeOriginal") == "25"


@pytest.mark.parametrize("form", ["json", "text"])
def test_grouping_file_overrides_and_unlisted_photos_stay_single(tmp_path, form):
    truth = scene()
    a = write_bracket_folder(tmp_path / "p", truth, [0.0025, 0.01, 0.04], "a")
    write_bracket_folder(tmp_path / "p", scene(seed=5), [0.01], "z")
    groups = tmp_path / f"groups.{form}"
    groups.write_text(json.dumps([[p.name for p in a[:2]]]) if form == "json" else
                      "# one view a line\na1: a0.jpg a1.jpg  # the first two\n")
    out = tmp_path / "hdr"
    r = run_cli("hdr", str(tmp_path / "p"), "-o", str(out), "--group-file", str(groups),
                "--json", "-q", "--working-space", "lin_rec709")
    assert r.returncode == 0, r.stderr
    grouping = json.loads(r.stdout)["grouping"]
    assert [v["photos"] for v in grouping["views"]] == [
        ["a0.jpg", "a1.jpg"], ["a2.jpg"], ["z0.jpg"]]
    assert grouping["views"][0]["how"] == "grouping file"
    assert "2 photo(s) not in the grouping file" in grouping["warnings"][0]
    header = read_image(out / "a1.exr").metadata  # named after its middle exposure
    assert header["gaslight:bracket"] == "a0.jpg,a1.jpg"
    assert header["gaslight:grouped_by"] == "grouping file"


@pytest.mark.parametrize("content, message", [
    ({"v": ["a0.jpg"], "w": ["a0.jpg", "a1.jpg"]}, "photo a0.jpg is listed twice"),
    ({"../v": ["a0.jpg", "a1.jpg"]}, "cannot name a file"),
    ({"a2": ["a0.jpg", "a1.jpg"]}, "would name two HDR views"),
    ({"v": ["a0.jpg", "nope.jpg"]}, "not in the input: nope.jpg"),
    ({"v": []}, "lists no photos"),
])
def test_bad_grouping_files_are_refused_with_one_line(tmp_path, content, message):
    write_bracket_folder(tmp_path / "p", scene(), [0.0025, 0.01, 0.04], "a")
    groups = tmp_path / "groups.json"
    groups.write_text(json.dumps(content))
    out = tmp_path / "hdr"
    r = run_cli("hdr", str(tmp_path / "p"), "-o", str(out), "--group-file", str(groups))
    assert r.returncode == 3 and message in r.stderr and "Traceback" not in r.stderr
    assert str(groups) in r.stderr
    assert not out.exists()


@pytest.mark.parametrize("source", SCENES)
def test_similarity_separates_brackets_from_neighbouring_views(tmp_path, source):
    """Exposure neighbours of hand-held AEB brackets (brightest >= 60 % clipped) score at
    least SAME_VIEW_SIMILARITY; no two photos of the bundled example (neighbouring views
    of one room, a smooth ceiling among them) do. Prints both sides of the margin."""
    from gaslight_usd.evaluation.bracket_shoot import aeb_shoot
    from gaslight_usd.locate import example_room
    from gaslight_usd.uplift.grouping import SAME_VIEW_SIMILARITY
    from gaslight_usd.uplift.similarity import similarity, thumbnail

    scenes = SCENES[source]()
    shoot = aeb_shoot(scenes[:5], tmp_path / "p", scenes[5:7])
    same = []
    for pos in shoot.positions:
        frames = sorted(pos.frames, key=lambda f: f.true_time)
        thumbs = [thumbnail(v) for v in load_views([f.path for f in frames], "srgb_tx",
                                                   "lin_rec709")]
        same += [similarity(a, b) for a, b in zip(thumbs[:-1], thumbs[1:], strict=True)]
    measured = [s for s in same if s is not None]
    photos = sorted((example_room() / "photos").glob("*.jpg"))
    thumbs = [thumbnail(v) for v in load_views(photos, "srgb_tx", "lin_rec709")]
    other = [similarity(thumbs[i], thumbs[j]) for i in range(len(thumbs))
             for j in range(i + 1, len(thumbs))]
    other = [s for s in other if s is not None]
    print(f"\n{source}: bracket neighbours min {min(measured):.3f} ({len(measured)} of "
          f"{len(same)} pairs measurable); example's different views max {max(other):.3f} "
          f"({len(other)} pairs); threshold {SAME_VIEW_SIMILARITY}")
    assert len(measured) >= 0.7 * len(same)
    assert min(measured) >= SAME_VIEW_SIMILARITY > max(other)
