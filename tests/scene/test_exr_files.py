"""Blender's own EXR writer against the project's reader, and against Blender's loader where it works."""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy", reason="needs bpy (installed by the README's set-up)")

from addon.core.exr import read_exr  # noqa: E402


def test_a_file_blender_writes_reads_back_exactly(scene, tmp_path):
    rng = np.random.default_rng(5)
    H, W = 6, 9
    rgba = rng.random((H, W, 4)).astype(np.float32)
    img = bpy.data.images.new("exr check", W, H, float_buffer=True, alpha=True)
    img.pixels.foreach_set(rgba[::-1].ravel())  # Blender's rows run bottom-up
    settings = scene.render.image_settings
    settings.file_format, settings.color_depth, settings.color_mode, settings.exr_codec = "OPEN_EXR", "32", "RGB", "NONE"
    path = tmp_path / "check.exr"
    img.save_render(str(path), scene=scene)
    bpy.data.images.remove(img)
    np.testing.assert_allclose(read_exr(path), rgba[..., :3], rtol=0, atol=1e-7)
