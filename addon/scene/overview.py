"""An overview picture of the cell: the cell from outside, and what the two probe cameras see.

The outside view is framed automatically on the cell's bounding box and lit by a
temporary sun and a brighter ambient; the laser is made brighter for it so the
line shows at this scale. The probe images are rendered with the probe settings.
All three go side by side into one PNG (sRGB, 8 bit).
"""

from __future__ import annotations

import math
from pathlib import Path

import bpy
import cv2
import numpy as np
from mathutils import Vector

from ..core.files import write_png
from .cell import SceneCell
from ..core.config.render import RenderOptions
from .render import configure, ctrl_c_after_render, render_animation, render_still

VIEW_DIRECTION = Vector((1.0, -1.25, 0.75)).normalized()  # from the front right, above


def _bounds(objects) -> tuple[Vector, Vector]:
    pts = [o.matrix_world @ Vector(c) for o in objects if o.type == "MESH" for c in o.bound_box]
    lo = Vector((min(p[i] for p in pts) for i in range(3)))
    hi = Vector((max(p[i] for p in pts) for i in range(3)))
    return lo, hi


def to_srgb8(img: np.ndarray) -> np.ndarray:
    """Linear float RGB -> 8-bit sRGB, as OpenCV's BGR."""
    x = np.clip(img, 0.0, 1.0)
    x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return cv2.cvtColor((x * 255 + 0.5).astype(np.uint8), cv2.COLOR_RGB2BGR)


def render_overview(sc: SceneCell, path: str | Path, width: int = 720, height: int = 480,
                    samples: int = 24, frame: int | None = None, focus: list | None = None,
                    before_write=None) -> Path:
    """Render the overview PNG for the current pose (or ``frame``) and write it atomically.

    ``focus``: objects to frame (default: the whole cell); ``before_write()``: called once the
    renders are done, before the picture is written (a stop asked for meanwhile raises there)."""
    scene = sc.scene
    if frame is not None:
        scene.frame_set(frame)
    current = scene.frame_current
    # Some ambient light so the workpiece shows around the line.
    probe_imgs = sc.render(current, current, RenderOptions(ambient=0.12, samples=16, filter_width_px=1.0))[0]

    lo, hi = _bounds(focus or [o for o in sc.root.all_objects])
    centre = (lo + hi) / 2
    radius = (hi - lo).length / 2
    cam_data = bpy.data.cameras.new("Overview")
    cam_data.lens = 35.0
    cam = bpy.data.objects.new("Overview", cam_data)
    scene.collection.objects.link(cam)
    fov = 2 * math.atan(cam_data.sensor_width / 2 / cam_data.lens) * min(1.0, height / width)
    cam.location = centre + VIEW_DIRECTION * (radius / math.sin(fov / 2)) * 0.95
    cam.rotation_euler = (centre - cam.location).to_track_quat("-Z", "Y").to_euler()
    cam_data.clip_start, cam_data.clip_end = 0.01, 100.0
    sun = bpy.data.objects.new("Overview sun", bpy.data.lights.new("Overview sun", "SUN"))
    sun.data.energy = 2.5
    sun.rotation_euler = (math.radians(40), math.radians(10), math.radians(30))
    scene.collection.objects.link(sun)
    lights = [o.data for o in sc.laser if o.type == "LIGHT"]
    powers = [light.energy for light in lights]
    # The settings' updates free Cycles' engines too, whose finaliser would swallow a Ctrl-C
    # (see SceneCell.render): the deferral holds to the end of the clean-up.
    with ctrl_c_after_render():
        try:
            configure(scene, sc.probe, RenderOptions(samples=samples, filter_width_px=1.5,
                                                      pixel_filter="BLACKMAN_HARRIS", ambient=0.35), cam)
            for light, power in zip(lights, powers):
                light.energy = power * 8.0
            outside = render_still(scene, cam, width, height)
        finally:
            for light, power in zip(lights, powers):
                light.energy = power
            bpy.data.objects.remove(cam, do_unlink=True)
            bpy.data.objects.remove(sun, do_unlink=True)

    def label(img, text):
        cv2.putText(img, text, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1, cv2.LINE_AA)
        return img

    if before_write is not None:
        before_write()
    panes = [label(to_srgb8(outside), "cell")]
    for camera, img in enumerate(probe_imgs):
        # Scale the probe image so the line's peak sits at 90 % of white.
        scaled = img / max(float(img[..., 0].max()) / 0.9, 1e-6)
        h = height // 2 if len(probe_imgs) == 2 else height
        w = int(round(img.shape[1] * h / img.shape[0]))
        big = cv2.resize(to_srgb8(scaled), (w, h), interpolation=cv2.INTER_NEAREST)
        panes.append(label(big, f"camera {camera}"))
    right = np.vstack(panes[1:])
    if right.shape[0] < height:
        right = np.vstack([right, np.zeros((height - right.shape[0], right.shape[1], 3), np.uint8)])
    picture = np.hstack([panes[0], right])
    return write_png(path, picture)
