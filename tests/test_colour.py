import numpy as np
import PyOpenColorIO as OCIO
import pytest

from gaslight_usd import colour
from gaslight_usd.errors import InputError


def test_convert_matches_ocio_apply_rgb():
    rng = np.random.default_rng(1)
    pixels = rng.random((5, 7, 3)).astype(np.float32) * 4.0
    ours = colour.convert(pixels, "Linear Rec.709 (sRGB)", "ACEScg")
    config = OCIO.Config.CreateFromFile(colour.BUILTIN_CONFIG)
    cpu = config.getProcessor("Linear Rec.709 (sRGB)", "ACEScg").getDefaultCPUProcessor()
    reference = np.array([cpu.applyRGB([float(v) for v in px]) for px in pixels.reshape(-1, 3)])
    np.testing.assert_allclose(ours.reshape(-1, 3), reference, rtol=1e-5, atol=1e-6)


def test_srgb_decode_known_values():
    # IEC 61966-2-1: encoded 0.5 -> linear 0.21404; 1.0 -> 1.0; 0.04045 -> 0.0031308
    encoded = np.array([[[0.5, 1.0, 0.04045]]], np.float32)
    linear = colour.convert(encoded, "srgb_tx", "lin_rec709")
    np.testing.assert_allclose(linear[0, 0], [0.214041, 1.0, 0.0031308], rtol=2e-4)


def test_white_is_preserved_into_acescg():
    white = np.ones((1, 1, 3), np.float32)
    np.testing.assert_allclose(colour.convert(white, "lin_rec709", "ACEScg")[0, 0], 1.0,
                               atol=1e-4)


def test_aliases_and_usd_tokens():
    assert colour.resolve_space("lin_ap1") == "ACEScg"
    assert colour.space_info("ACEScg").usd_token == "lin_ap1_scene"
    assert colour.space_info("lin_rec709").usd_token == "lin_rec709_scene"
    assert colour.space_info("srgb_tx").is_scene_linear is False


def test_unknown_space_lists_closest_names():
    with pytest.raises(InputError) as err:
        colour.resolve_space("ACES cg")
    assert "ACEScg" in str(err.value)
    assert "\n" not in str(err.value)


def test_env_ocio_is_used_unless_explicit(monkeypatch):
    monkeypatch.setenv("OCIO", "ocio://studio-config-latest")
    assert colour.resolve_config_uri() == "ocio://studio-config-latest"
    assert colour.resolve_config_uri("ocio://cg-config-latest") == "ocio://cg-config-latest"
    monkeypatch.delenv("OCIO")
    assert colour.resolve_config_uri() == colour.BUILTIN_CONFIG


def test_bad_config_is_an_input_error():
    with pytest.raises(InputError, match="cannot load OCIO config"):
        colour.load_config("/nonexistent/config.ocio")


def test_luminance_weights_sum_to_one():
    for space in ("ACEScg", "lin_rec709"):
        assert colour.luminance_weights(space).sum() == pytest.approx(1.0, abs=2e-3)
