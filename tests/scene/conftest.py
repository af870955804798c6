"""Scene tier: bpy and Cycles on the CPU. Each test starts from an empty factory scene."""

import pytest

bpy = pytest.importorskip("bpy", reason="the scene tier needs bpy (installed by the README's set-up)")


@pytest.fixture
def scene():
    from addon.scene.session import new_scene

    return new_scene()
