"""The [sensor] table and the workpiece surface in scan configs."""

from pathlib import Path

import numpy as np
import pytest

from addon.core.errors import ConfigError, InputError
from addon.core.config.scan import load_scan_config
from addon.core.optics.sensor import SensorModel

REPO = Path(__file__).resolve().parents[2]
STEP = (REPO / "rigs" / "scenes" / "step_block.toml").read_text()


def config(tmp_path, extra: str = "", workpiece: str = ""):
    path = tmp_path / "scan.toml"
    path.write_text(STEP.replace("[workpiece]\n", "[workpiece]\n" + workpiece) + "\n" + extra)
    return load_scan_config(path)


def test_without_a_sensor_table_the_sensor_is_ideal(tmp_path):
    cfg = config(tmp_path)
    assert cfg.sensor == SensorModel() and cfg.sensor.ideal
    assert cfg.detect.saturation == np.inf and cfg.material == "grey"


def test_sensor_keys_reach_the_model(tmp_path):
    cfg = config(tmp_path, "[sensor]\nsaturate = true\nnoise = true\nbit_depth = 10\nexposure_ms = 0.5\n"
                           "distortion = [-0.05, 0.01, 0.0, 0.0]\nseed = 42\n",
                 'material = "glossy"\nroughness = 0.05\n')
    s = cfg.sensor
    assert (s.saturate, s.noise, s.bit_depth, s.exposure_ms, s.seed) == (True, True, 10, 0.5, 42)
    assert s.distortion == (-0.05, 0.01, 0.0, 0.0) and not s.speckle
    assert cfg.detect.saturation == 1.0  # a clipping sensor: the detector flags full-scale lines
    assert (cfg.material, cfg.roughness) == ("glossy", 0.05)


@pytest.mark.parametrize("extra,workpiece,fragment", [
    ("[sensor]\nbit_depth = 9\n", "", "sensor.bit_depth: must be one of 8, 10, 12, 16, got 9"),
    ("[sensor]\nbit_depth = -8\n", "", "sensor.bit_depth: must be one of 8, 10, 12, 16, got -8"),
    ("[sensor]\ntarget_peak = 0\n", "", "sensor.target_peak: 0 is out of range; allowed (0, 1]"),
    ("[sensor]\nnosie = true\n", "", "unknown key sensor.nosie"),
    ("[sensor]\nnosie = true\n", "", "distortion"),  # listed among the allowed keys
    ("[sensor]\ndistortion = [0.1]\n", "", "sensor.distortion"),
    ("[sensor]\nexposure_ms = 0\n", "", "sensor.exposure_ms"),
    ("[sensor]\nmotion_blur = true\nexposure_ms = 20.0\n", "", "longer than 0.98 of a frame"),
    ("[sensor]\nnoise = 1\n", "", "sensor.noise"),
    ("", 'material = "chrome"\n', "grey, dark, glossy, mirror"),
    ("", "roughness = 2.0\n", "workpiece.roughness"),
    # taken, and doing nothing (a hunt): each needs its effect on, or one value for one thing
    ("[sensor]\nsaturate = true\ntarget_peak = 0.5\n", "", "sensor.target_peak: acts only with auto_exposure = true"),
    ("[sensor]\nf_number = 4.0\n", "", "sensor.f_number: acts only with speckle or defocus = true"),
    ("[sensor]\ndefocus = true\nwavelength_nm = 905.0\n", "", "sensor.wavelength_nm: acts only with speckle = true"),
    ("[sensor]\nspeckle = true\nfocus_mm = 150.0\n", "", "sensor.focus_mm: acts only with defocus = true"),
    ("[sensor]\nspeckle = true\nf_number = 0.3\n", "", "sensor.f_number: 0.3 is out of range"),
    ("[sensor]\nspeckle = true\npixel_pitch_um = 40.0\nsensor_width_mm = 3.0\n", "",
     "sensor.pixel_pitch_um: and sensor_width_mm both set the pixel pitch"),
])
def test_bad_sensor_and_surface_keys_name_what_is_allowed(tmp_path, extra, workpiece, fragment):
    with pytest.raises(ConfigError) as err:
        config(tmp_path, extra, workpiece)
    assert fragment in str(err.value) and str(err.value).startswith(str(tmp_path / "scan.toml"))


def test_with_realism_swaps_sensor_surface_and_ambient(tmp_path):
    cfg = config(tmp_path)
    real = cfg.with_realism(SensorModel(saturate=True), "dark", None, 0.2)
    assert real.detect.saturation == 1.0 and real.material == "dark" and real.render.ambient == 0.2
    assert real.roughness == cfg.roughness and cfg.sensor.ideal  # the original is untouched
    with pytest.raises(InputError, match="material"):
        cfg.with_realism(SensorModel(), "chrome")


def test_frames_are_parsed_or_refused_by_name():
    from addon.core.config.scan import parse_frames
    from addon.core.errors import InputError

    assert parse_frames(None) is None and parse_frames("") is None
    assert parse_frames("5") == slice(5, 6)
    assert list(range(10))[parse_frames("-1")] == [9] and list(range(10))[parse_frames("-2")] == [8]  # from the end
    assert parse_frames("0:40") == slice(0, 40) and parse_frames("::2") == slice(None, None, 2)
    for bad, message in (("0:4:0", "step must be"), ("0:4:-1", "step must be"), ("a:b", "expected A:B"),
                         ("1:2:3:4", "expected A:B"), ("x", "expected A:B")):
        with pytest.raises(InputError, match=message):
            parse_frames(bad, "--frames")


def test_eevee_gets_the_spot_laser_unless_a_config_chooses(tmp_path):
    # Eevee ignores the gobo's node tree; its default laser is the spots' Gaussian line.
    def with_render(lines: str):
        return config(tmp_path, "[render]\n" + lines)

    assert with_render("").render.laser == "gobo"
    assert with_render('engine = "eevee"\n').render.laser == "spot"
    assert with_render('engine = "eevee"\nlaser = "slit"\n').render.laser == "slit"
    with pytest.raises(ConfigError, match="spot"):
        with_render('engine = "eevee"\nlaser = "gobo"\n')
    # --engine eevee on the command line: the gobo becomes the spots, a chosen slit stays.
    assert config(tmp_path).with_overrides(engine="eevee").render.laser == "spot"
    assert with_render('laser = "slit"\n').with_overrides(engine="eevee").render.laser == "slit"
    # Cycles samples one of the spots per path: their line is Eevee's, the gobo is Cycles'.
    with pytest.raises(ConfigError, match="gobo"):
        with_render('laser = "spot"\n')
    eevee = with_render('engine = "eevee"\n')
    assert eevee.with_overrides(engine="cycles").render.laser == "gobo"


@pytest.mark.parametrize("sensor,key", [
    ("bit_depth = 8\n", "bit_depth"),
    ("auto_exposure = true\nexposure_ms = 0.001\n", "auto_exposure"),
    ("saturate = true\nprnu = 0.05\n", "prnu"),
    ("noise = true\nframe_rate_hz = 200.0\n", "frame_rate_hz"),
])
def test_a_sensor_parameter_whose_effect_is_off_is_refused(tmp_path, sensor, key):
    """An 8-bit sensor, auto-exposure at 1 µs and a gain of 0.01 with neither saturate nor
    noise on scanned exactly as the ideal sensor, the report saying "ideal"."""
    with pytest.raises(ConfigError, match=f"sensor.{key}: acts only with"):
        config(tmp_path, "[sensor]\n" + sensor)
    switches = "".join(f"{w} = true\n" for w in ("saturate", "noise", "motion_blur") if f"{w} =" not in sensor)
    assert config(tmp_path, "[sensor]\n" + switches + sensor).sensor
