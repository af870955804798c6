"""The two probe cameras, set so that Blender projects a point to the pixel ``probe.project`` gives.

Mapping (checked by rendering markers): horizontal sensor fit with
lens = f_px · sensor_width / W, camera orientation = OpenCV camera-to-probe
rotation · diag(1, −1, −1). Blender's principal point is the image centre, which
in OpenCV's pixel-centre convention is ((W − 1)/2, (H − 1)/2), the probe's, so no
lens shift is needed. The cameras are named with the multiview suffixes _L
(camera 0) and _R (camera 1), so one render pass produces both images.
"""

from __future__ import annotations

import bpy
import numpy as np

from ..core.optics.probe import Probe
from .units import CV_TO_BLENDER_CAMERA, from_blender, to_blender

SENSOR_WIDTH_MM = 36.0
CAMERA_BASENAME = "ProbeCam"
SUFFIXES = ("_L", "_R")  # camera 0, camera 1
CLIP_START_M = 0.001  # 1 mm: the range starts 70 mm out, Blender's 0.1 m default would hide it
EEVEE_CLIP_START_M = 0.01  # Eevee's depth buffer needs it further out (see render.configure)


def camera_name(camera: int) -> str:
    return CAMERA_BASENAME + SUFFIXES[camera]


def add_probe_cameras(collection, probe: Probe, parent: bpy.types.Object) -> list[bpy.types.Object]:
    cams = []
    for camera in (0, 1):
        data = bpy.data.cameras.new(camera_name(camera))
        data.sensor_fit = "HORIZONTAL"
        data.sensor_width = SENSOR_WIDTH_MM
        data.lens = probe.f_px * SENSOR_WIDTH_MM / probe.cols_px
        data.clip_start = CLIP_START_M
        data.clip_end = 10.0
        obj = bpy.data.objects.new(camera_name(camera), data)
        collection.objects.link(obj)
        obj.parent = parent
        obj.matrix_parent_inverse.identity()
        obj.matrix_basis = to_blender(probe.cam2probe(camera) @ CV_TO_BLENDER_CAMERA)
        cams.append(obj)
    return cams


def probe_cameras(camera_left: bpy.types.Object) -> list[bpy.types.Object]:
    """Camera 0 and, found by the multiview suffix, camera 1 (none if ``camera_left`` is no probe camera)."""
    if not camera_left.name.startswith(camera_name(0)):
        return []
    base, _, tail = camera_left.name.partition(SUFFIXES[0])
    right = bpy.data.objects.get(base + SUFFIXES[1] + tail)
    return [camera_left] + ([right] if right is not None and right.type == "CAMERA" else [])


def camera_to_world_cv(obj: bpy.types.Object) -> np.ndarray:
    """(4, 4) mm: the OpenCV camera frame of a probe camera in the world, as Blender has it."""
    return from_blender(obj.matrix_world) @ CV_TO_BLENDER_CAMERA
