"""RenderOptions: a script's settings of the wrong kind are named in one line."""

import pytest

from addon.core.errors import InputError


@pytest.mark.parametrize("kw, words", [
    (dict(ambient="1"), "ambient must be a number in [0, 100]"),
    (dict(filter_width_px=None), "filter width (px) must be a number"),
    (dict(motion_blur_shutter=float("nan")), "motion blur shutter (frames) must be a number in [0, 0.98]"),
    (dict(laser_peak=0), "laser peak must be a number in (0, 1000]"),
    (dict(laser_peak=-1), "laser peak must be a number in (0, 1000]"),
    (dict(persistent_data="yes"), "persistent data must be True or False"),
])
def test_render_options_of_the_wrong_kind_are_named(kw, words):
    """A script's RenderOptions (a review: a string or None gave Python's TypeError)."""
    from addon.core.config.render import RenderOptions

    with pytest.raises(InputError) as err:
        RenderOptions(**kw)
    assert words in str(err.value)


def test_cycles_box_filter_narrower_than_a_pixel_is_refused_above_one_sample(tmp_path):
    """Cycles' box is one pixel wide whatever its width: at 16 samples a 0.5 px box (or the
    default 0.01, "a point sample") rendered the very images of the 1 px box. A config that
    gives more samples and no width takes the 1 px box, as does --samples on a point-sampled one."""
    from pathlib import Path

    from addon.core.config.render import RenderOptions
    from addon.core.config.scan import load_scan_config
    from addon.core.errors import ConfigError

    with pytest.raises(InputError, match="one pixel wide whatever its width"):
        RenderOptions(samples=16)
    assert RenderOptions(samples=16, filter_width_px=1.0).filter_width_px == 1.0
    assert RenderOptions(samples=1).filter_width_px == 0.01  # one sample: a point whatever the box
    assert RenderOptions(engine="eevee", samples=16).filter_width_px == 0.01  # Eevee's filter takes its width
    demo = (Path(__file__).resolve().parents[2] / "rigs" / "scenes" / "demo.toml").read_text()
    many = tmp_path / "many.toml"
    assert "samples = 1\nfilter_width_px = 0.01\n" in demo
    many.write_text(demo.replace("samples = 1\nfilter_width_px = 0.01\n", "samples = 16\n", 1))
    assert load_scan_config(many).render.filter_width_px == 1.0
    narrow = tmp_path / "narrow.toml"
    narrow.write_text(many.read_text().replace("samples = 16\n", "samples = 16\nfilter_width_px = 0.5\n", 1))
    with pytest.raises(ConfigError, match="filter_width_px: Cycles' box"):
        load_scan_config(narrow)
    assert load_scan_config("demo").with_overrides(samples=16).render.filter_width_px == 1.0


@pytest.mark.parametrize("keys,fragment", [('pixel_filter = "GAUSSIAN"\n', "pixel_filter: Eevee has a pixel filter"),
                                            ("bounces = 2\n", "bounces: 2: Eevee traces no bounces")])
def test_eevee_refuses_the_render_keys_it_would_ignore(tmp_path, keys, fragment):
    """Eevee rendered a BOX and a GAUSSIAN filter of the same width to the same bits, and 2
    bounces as none, without a word."""
    from pathlib import Path

    from addon.core.config.scan import load_scan_config
    from addon.core.errors import ConfigError

    demo = (Path(__file__).resolve().parents[2] / "rigs" / "scenes" / "demo.toml").read_text()
    path = tmp_path / "eevee.toml"
    path.write_text(demo.replace('engine = "cycles"\n', 'engine = "eevee"\n' + keys, 1).replace('laser = "gobo"\n', ""))
    with pytest.raises(ConfigError, match=fragment):
        load_scan_config(path)


def test_an_engine_override_follows_the_same_rules(tmp_path):
    """--engine cycles on an Eevee config of 16 samples failed with the box filter's own
    message; --engine eevee took a config's bounces and filter without a word."""
    from dataclasses import replace

    from addon.core.config.scan import load_scan_config

    demo = load_scan_config("demo")
    eevee = replace(demo, render=replace(demo.render, engine="eevee", laser="spot", samples=16))
    assert eevee.with_overrides(engine="cycles").render.filter_width_px == 1.0
    with pytest.raises(InputError, match="--engine .engine. eevee: this config's .render. bounces = 2"):
        load_scan_config("cylinder_realistic").with_overrides(engine="eevee")
    gauss = replace(demo, render=replace(demo.render, pixel_filter="GAUSSIAN", filter_width_px=1.5))
    with pytest.raises(InputError, match="pixel_filter = 'GAUSSIAN'"):
        gauss.with_overrides(engine="eevee")
    assert demo.with_overrides(engine="eevee").render.engine == "eevee"
