"""The pictures drawn without Blender: the growth strip of an adaptive scan."""

import numpy as np
import trimesh

from addon.core.scan.preview import EARLIER_BGR, NEW_BGR, growth_strip


def _count(panel, colour):
    return int(np.all(panel == np.array(colour, np.uint8), axis=2).sum())


def test_the_growth_strip_shows_each_view_new_in_its_panel_and_earlier_after():
    box = trimesh.creation.box([40.0, 40.0, 20.0])
    box.apply_translation([0.0, 0.0, 10.0])
    g = np.linspace(-15.0, 15.0, 30)
    x, y = np.meshgrid(g, g)
    top = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, 20.0)])
    left, right = top[top[:, 0] < -1.0], top[top[:, 0] > 1.0]  # two views' points on the top face
    points = np.vstack([left, right])
    view = np.r_[np.zeros(len(left), int), np.ones(len(right), int)]
    strip = growth_strip(box, points, view, ["view 1", "view 2"], size=(300, 240))
    assert strip.shape == (240, 600, 3) and strip.dtype == np.uint8
    first, second = strip[:, :300], strip[:, 300:]
    # Panel 1: only the first view's points, as new; panel 2: the first as earlier, the second as new.
    assert _count(first, NEW_BGR) > 100 and _count(first, EARLIER_BGR) == 0
    assert _count(second, EARLIER_BGR) > 100 and _count(second, NEW_BGR) > 100
    assert abs(_count(second, EARLIER_BGR) - _count(first, NEW_BGR)) <= 0.1 * _count(first, NEW_BGR)
    # Points hidden under the part (its bottom face) are not drawn (a few at its outline may be).
    seen = growth_strip(box, top, np.zeros(len(top), int), ["top"], size=(300, 240))
    hidden = growth_strip(box, top * [1, 1, 0], np.zeros(len(top), int), ["under"], size=(300, 240))
    assert _count(hidden, NEW_BGR) < 0.05 * _count(seen, NEW_BGR)


def test_colour_bar_labels_keep_two_figures_however_small_the_scale():
    from addon.core.scan.preview import bar_label

    # A bar whose top is 1.3 µm used to read 1, 1, 0.
    labels = [bar_label(f * 1.3, 1.3) for f in (0.0, 0.5, 1.0)]
    assert labels == ["0.0", "0.7", "1.3"] and len(set(labels)) == 3
    assert [bar_label(f * 55.0, 55.0) for f in (0.0, 0.5, 1.0)] == ["0", "28", "55"]
    assert bar_label(0.4, 0.4) == "0.40" and bar_label(250.0, 250.0) == "250"
    assert bar_label(0.0, 1e-6) == "0.000" and bar_label(float("nan"), float("nan")) == "nan"


def test_the_preview_draws_points_on_fixtures_in_their_own_colour():
    from addon.core.scan.preview import FIXTURE_BGR, render_preview

    box = trimesh.creation.box([40.0, 40.0, 20.0])
    box.apply_translation([0.0, 0.0, 10.0])
    g = np.linspace(-60.0, 60.0, 60)
    x, y = np.meshgrid(g, g)
    table = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    fixture = table[:, 0] > 30.0  # say these lie on a clamp
    err = np.zeros(len(table))
    off = np.zeros(len(table), bool)
    without = render_preview(box, table, err, off, "t", size=(400, 300))
    with_fixture = render_preview(box, table, err, off, "t", size=(400, 300), on_fixture=fixture)
    assert _count(without, FIXTURE_BGR) == 0 and _count(with_fixture, FIXTURE_BGR) > 100
    assert _count(with_fixture, (150, 150, 150)) < _count(without, (150, 150, 150))


def test_points_far_beyond_the_colour_scale_stand_out_and_are_counted():
    """Most of a box's top read 1-2 µm and the scale ends at their 95th percentile; 12 points
    at 130 µm (a rim's error) would be drawn in the scale's top colour, like the best points'
    worst 5 %. They are drawn in their own colour instead, over the rest, and only they."""
    from addon.core.scan.preview import BEYOND_BGR, render_preview

    box = trimesh.creation.box([40.0, 40.0, 20.0])
    box.apply_translation([0.0, 0.0, 10.0])
    g = np.linspace(-18.0, 18.0, 40)
    x, y = np.meshgrid(g, g)
    top = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, 20.0)])
    err = np.random.default_rng(0).uniform(1.0, 2.0, len(top))
    on = np.ones(len(top), bool)
    plain = render_preview(box, top, err, on, "t", size=(400, 300))
    rim = np.argsort(top[:, 0])[-12:]  # the points along one edge
    err[rim] = 130.0
    marked = render_preview(box, top, err, on, "t", size=(400, 300))
    assert _count(plain, BEYOND_BGR) == 0
    assert _count(marked, BEYOND_BGR) >= 12 * 5  # each a dot of a few pixels, and the legend's


def test_a_title_too_long_for_one_line_is_broken_after_a_comma_and_kept_clear_of_the_colour_bar():
    from addon.core.scan.preview import render_preview

    box = trimesh.creation.box([40.0, 30.0, 20.0])
    box.apply_translation([0.0, 0.0, 10.0])
    points = trimesh.sample.sample_surface(box, 500, seed=1)[0]
    errors, on_part = np.linspace(0.0, 5.0, len(points)), np.ones(len(points), bool)

    def ink(img):  # dark title pixels on the first and the second text line, left of the colour bar
        dark = (img < 90).all(axis=2)
        return dark[12:32, :780].sum(), dark[36:54, :780].sum()

    short = render_preview(box, points, errors, on_part, "block: 500 points")
    long = render_preview(box, points, errors, on_part, "a configuration with a long name: 500 points, RMS 1.0 um, "
                          "p95 1.4 um, covers 98 % of what the path can measure, 23 % of the whole part")
    assert ink(short)[0] > 0 and ink(short)[1] == 0  # one line
    assert ink(long)[0] > 0 and ink(long)[1] > 0    # two lines
    assert not (long[12:32, 786:] < 90).all(axis=2).any()  # nothing of the title over the colour bar's column
