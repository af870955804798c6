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
