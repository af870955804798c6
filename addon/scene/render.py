"""Rendering the probe cameras: settings, one animation call for many frames, images back as arrays.

Both probe cameras render in one pass through multiview (views ``_L`` = camera 0
and ``_R`` = camera 1, matched by camera-name suffix). Frames are rendered as
one animation (the path is keyframed), written as 32-bit float EXR (linear,
no view transform, no 8-bit quantisation) and read back as float32 (H, W, 3)
arrays in OpenCV row order (row 0 at the top).

What the probe images do not need is left out: no light bounces for diffuse
scenes, no denoising, no passes beyond the combined image, no world light
beyond an optional dim ambient. With 1 sample and a box filter of 0.01 px each
pixel is point-sampled at its centre: deterministic and exact for the smooth
Gaussian line profile of the gobo laser.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path

import bpy
import numpy as np

from ..core.config.render import RenderOptions
from ..core.errors import InputError
from ..core.exr import read_exr
from ..core.optics.probe import MAX_RENDER_PIXELS, Probe
from ..core.optics.sensor import MAX_SHUTTER_FRAMES
from .cameras import CLIP_START_M, EEVEE_CLIP_START_M, probe_cameras
from .compat import ensure_node_tree, new_world
from .compat import BLENDER_ENGINES
from .blender_log import blender_output_captured
from .session import use_device

VIEWS = (("left", "_L"), ("right", "_R"))

EXPOSURE_KEY_FRAMES = MAX_SHUTTER_FRAMES / 2  # a frame's motion-blur keys sit this far either side of it (Blender frames)


def configure(scene: bpy.types.Scene, probe: Probe, settings: RenderOptions, camera_left: bpy.types.Object) -> str:
    """Set the scene up for probe renders; returns the device used (Cycles': the one it was
    given; Eevee's: the OpenGL device once it has rendered, see :func:`opengl_device`)."""
    r = scene.render
    r.engine = BLENDER_ENGINES[settings.engine]
    W, H = probe.cols_px, probe.rows_px
    if max(W, H) > MAX_RENDER_PIXELS:  # Blender would render it smaller without a word
        raise InputError(f"a {W} x {H} px sensor: Blender renders at most {MAX_RENDER_PIXELS} px a side; use a "
                         f"smaller sensor, or the raycast engine")
    r.resolution_x, r.resolution_y, r.resolution_percentage = W, H, 100
    r.pixel_aspect_x = r.pixel_aspect_y = 1.0
    r.use_border = False
    r.film_transparent = False
    # What the scene's own post-processing or overrides would put into the probe images: the
    # compositor (a blur moved points), the sequencer (a strip replaced the image), Freestyle's
    # lines, Simplify, a view layer's material or sample override, the layers beside the one
    # rendered.
    r.use_compositing = r.use_sequencer = r.use_freestyle = r.use_simplify = False
    r.use_single_layer = True
    for layer in scene.view_layers:
        layer.material_override = None
        if hasattr(layer, "world_override"):  # (5.0 and later)
            layer.world_override = None
        layer.samples = 0
        layer.use_solid = layer.use_sky = layer.use_motion_blur = True
    r.use_persistent_data = settings.persistent_data
    if settings.threads is None:
        r.threads_mode = "AUTO"
    else:
        r.threads_mode, r.threads = "FIXED", int(settings.threads)
    r.use_motion_blur = settings.motion_blur_shutter > 0
    if r.use_motion_blur:
        # Within the motion keys either side of each frame (cell.exposure_keys): a whole frame's
        # shutter would reach the next frame's keys, across a jump between path entries.
        r.motion_blur_shutter = settings.motion_blur_shutter  # at most MAX_SHUTTER_FRAMES (RenderOptions)
        r.motion_blur_position = "CENTER"
    device = "CPU"
    if settings.engine == "eevee":
        device = opengl_device() or "GPU (OpenGL)"
    if settings.engine == "cycles":
        device = use_device(scene, settings.device)
        c = scene.cycles
        c.samples = settings.samples
        c.use_adaptive_sampling = False
        c.use_denoising = False
        c.pixel_filter_type = settings.pixel_filter
        c.filter_width = settings.filter_width_px
        c.seed = 0
        c.max_bounces = settings.bounces
        for name in ("diffuse_bounces", "glossy_bounces", "transmission_bounces", "volume_bounces"):
            setattr(c, name, settings.bounces)
        c.transparent_max_bounces = max(settings.bounces, 0)
        c.caustics_reflective = c.caustics_refractive = False
        c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
        # The scene's own choices that would change the probe images: as in a new scene.
        _as_new(c, ("film_exposure", "blur_glossy", "min_light_bounces", "min_transparent_bounces",
                    "use_animated_seed", "use_layer_samples"))
        c.use_light_tree = False  # one light: the tree only adds work (measured: −12 % time per frame)
        # Cycles drops (or, at random, boosts) light below 1 % of its strength by default:
        # that cuts the laser line's flanks, which every sub-pixel detector reads.
        c.light_sampling_threshold = 0.0
    else:
        _as_new(scene.eevee, ("clamp_surface_direct", "clamp_surface_indirect", "clamp_volume_direct",
                              "clamp_volume_indirect", "gi_glossy_clamp", "volumetric_light_clamp"))
        scene.eevee.taa_render_samples = settings.samples
        r.filter_size = max(settings.filter_width_px, 0.01)
    # Eevee shades each pixel at the point its depth buffer gives, and the buffer's
    # precision at the part scales with 1 / clip start: at 1 mm the laser line (whose
    # intensity changes fast across the view ray) moved by 0.004 px (tests/scene/test_optics.py).
    # Cycles traces rays and keeps 1 mm, so that nothing near a lens goes unseen.
    near = EEVEE_CLIP_START_M if settings.engine == "eevee" else CLIP_START_M
    for camera in probe_cameras(camera_left):
        camera.data.clip_start = near
    view = scene.view_settings
    view.view_transform = "Standard"
    view.look = "None"
    view.exposure = 0.0
    view.gamma = 1.0
    _world(scene, settings.ambient)
    for layer in scene.view_layers:
        layer.use_pass_z = False
    image = r.image_settings
    image.file_format = "OPEN_EXR"
    image.color_depth = "32"
    image.color_mode = "RGB"
    image.exr_codec = "NONE"
    r.use_multiview = True
    r.views_format = "MULTIVIEW"
    image.views_format = "INDIVIDUAL"
    for view_name, suffix in VIEWS:
        v = r.views.get(view_name) or r.views.new(view_name)
        v.camera_suffix = suffix
        v.use = True
    scene.camera = camera_left
    return device


def _as_new(struct, names) -> None:
    """Set the properties ``names`` of ``struct`` to what a new scene has (those this Blender
    lacks are skipped)."""
    for name in names:
        prop = struct.bl_rna.properties.get(name)
        if prop is not None:
            setattr(struct, name, tuple(prop.default_array) if getattr(prop, "is_array", False) else prop.default)


def use_views(scene: bpy.types.Scene, cameras=(0, 1)) -> None:
    """Render only the given probe cameras (a camera that sees nothing can be skipped)."""
    for index, (view_name, _) in enumerate(VIEWS):
        scene.render.views[view_name].use = index in cameras


SCANNER_WORLD = "Scanner probe world"


def _world(scene, strength: float) -> None:
    """Light the probe renders with the scanner's own world, a white background of ``strength``
    (the scene's world, whose background may be named otherwise, fed by a sky texture, or have
    no nodes, is left as it is; the panel puts it back afterwards)."""
    world = bpy.data.worlds.get(SCANNER_WORLD)
    bg = None if world is None or world.node_tree is None else world.node_tree.nodes.get("Background")
    out = None if bg is None else next((n for n in world.node_tree.nodes if n.type == "OUTPUT_WORLD"), None)
    if bg is None or bg.type != "BACKGROUND" or out is None or not bg.outputs[0].links \
            or any(i.is_linked for i in bg.inputs):  # changed since it was made: made again
        if world is not None:
            bpy.data.worlds.remove(world)
        world = new_world(SCANNER_WORLD)
        bg = ensure_node_tree(world).nodes["Background"]
    bg.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bg.inputs["Strength"].default_value = strength
    scene.world = world


RAISED_AFTER_RENDER = "Ctrl-C during a render: raised once the render call returned"


@contextlib.contextmanager
def ctrl_c_after_render():
    """A Ctrl-C during a render call, raised once the call is over instead of lost.

    Cycles runs Python callbacks while it renders; a KeyboardInterrupt raised inside one is
    caught and printed by Blender, which goes on (a user's script carried on after Ctrl-C).
    Where SIGINT has Python's own handler (a script, the Python prompt), the signal is only
    recorded during the call, and KeyboardInterrupt is raised when the call has returned and
    its files are cleaned up (a scan's render calls are sized to about a second; a second
    press meanwhile is recorded too, since raised inside Cycles it would be lost as well).
    Where the call fails after a Ctrl-C, the KeyboardInterrupt is raised from that failure. A
    program with a handler of its own (the command line's headless.lifecycle.StopRequests)
    and calls from other threads are left alone.
    """
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread() \
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield
        return
    asked = []
    signal.signal(signal.SIGINT, lambda signum, frame: asked.append(signum))
    try:
        yield
    except BaseException as exc:
        if asked and not isinstance(exc, KeyboardInterrupt):  # the stop comes first, the failure is its cause
            raise KeyboardInterrupt(RAISED_AFTER_RENDER) from exc
        raise
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if asked:
        raise KeyboardInterrupt(RAISED_AFTER_RENDER)



def read_image(path: str | Path) -> np.ndarray:
    """A rendered EXR file -> (H, W, 3) float32 RGB, row 0 at the top (OpenCV order).

    Read without Blender's image loader, which gives 0 × 0 images for multiview files
    on 4.5 (see ``addon.core.exr``)."""
    return read_exr(path)


def set_rows(scene: bpy.types.Scene, rows: tuple[int, int] | None) -> None:
    """Render only image rows r0..r1−1 (OpenCV order, top = 0), cropped; None renders all.

    Blender's border counts from the bottom in fractions of the height; these
    fractions give exactly the requested rows (checked pixel for pixel).
    """
    r = scene.render
    if rows is None:
        r.use_border = False
        return
    H = r.resolution_y
    r0, r1 = int(rows[0]), int(rows[1])
    if not 0 <= r0 < r1 <= H:
        raise InputError(f"row band {r0}..{r1} is not inside the image's {H} rows")
    r.use_border = True
    r.use_crop_to_border = True
    r.border_min_x, r.border_max_x = 0.0, 1.0
    r.border_min_y, r.border_max_y = (H - r1) / H, (H - r0) / H


def opengl_device() -> str | None:
    """What Eevee rendered on, from the GPU module (known once Eevee has rendered; None before
    or where the module cannot tell): "GPU (OpenGL: NVIDIA H100 ...)", or "CPU (software
    OpenGL: llvmpipe ...)" where no GPU drives OpenGL (Mesa's software rasteriser)."""
    try:
        import gpu

        renderer = gpu.platform.renderer_get()
        software = gpu.platform.device_type_get() == "SOFTWARE"
        backend = gpu.platform.backend_type_get().title().replace("Opengl", "OpenGL")
    except Exception:  # not initialised (no Eevee render yet), or a build without the module
        return None
    return f"CPU (software {backend}: {renderer})" if software else f"GPU ({backend}: {renderer})"


def render_animation(scene: bpy.types.Scene, first: int, last: int, cameras=(0, 1),
                     out_dir: str | Path | None = None, rows: tuple[int, int] | None = None
                     ) -> list[list[np.ndarray | None]]:
    """Render frames first..last (inclusive) in one call; returns [frame][camera] images.

    A camera not in ``cameras`` gives None. With ``rows`` = (r0, r1) only those image
    rows are rendered and returned (arrays of r1 − r0 rows). Images go through a
    temporary folder unless ``out_dir`` is given (then the EXR files stay there).
    """
    if last < first:
        raise InputError(f"frame range {first}..{last} is empty")
    if first < 0:  # Blender's frame_start stops at 0: it rendered frame 0 and the files were not found
        raise InputError(f"frame {first}: Blender renders frames from 0 on; go to frame 0 or later")
    with ctrl_c_after_render():
        return _render_animation(scene, first, last, cameras, out_dir, rows)


def _render_animation(scene, first, last, cameras, out_dir, rows):
    use_views(scene, cameras)
    set_rows(scene, rows)
    keep = out_dir is not None
    folder = Path(out_dir) if keep else Path(tempfile.mkdtemp(prefix="scanner-render-"))
    folder.mkdir(parents=True, exist_ok=True)
    r = scene.render
    old = (scene.frame_start, scene.frame_end, scene.frame_step, r.filepath, r.use_file_extension)
    scene.frame_start, scene.frame_end, scene.frame_step = first, last, 1
    r.filepath = str(folder / "frame_")
    r.use_file_extension = True
    try:
        with blender_output_captured():
            bpy.ops.render.render(animation=True)
        out = []
        for frame in range(first, last + 1):
            images = []
            for index, (_, suffix) in enumerate(VIEWS):
                path = folder / f"frame_{frame:04d}{suffix}.exr"
                images.append(read_image(path) if index in cameras else None)
                if not keep and index in cameras:
                    os.remove(path)
            out.append(images)
        return out
    finally:
        scene.frame_start, scene.frame_end, scene.frame_step, r.filepath, r.use_file_extension = old
        if not keep:  # with what a failed render left in it
            shutil.rmtree(folder, ignore_errors=True)


def render_still(scene: bpy.types.Scene, camera: bpy.types.Object, width: int, height: int) -> np.ndarray:
    """One image from ``camera`` (no multiview) as float32 (H, W, 3); render settings otherwise as they are."""
    with ctrl_c_after_render():
        return _render_still(scene, camera, width, height)


def _render_still(scene, camera, width, height):
    r = scene.render
    old = (r.use_multiview, scene.camera, r.resolution_x, r.resolution_y, r.filepath)
    folder = Path(tempfile.mkdtemp(prefix="scanner-still-"))
    try:
        r.use_multiview = False
        scene.camera = camera
        r.resolution_x, r.resolution_y = width, height
        r.filepath = str(folder / "still.exr")
        image = r.image_settings
        image.file_format, image.color_depth, image.color_mode, image.exr_codec = "OPEN_EXR", "32", "RGB", "NONE"
        with blender_output_captured():
            bpy.ops.render.render(write_still=True)
        return read_image(folder / "still.exr")
    finally:
        r.use_multiview, scene.camera, r.resolution_x, r.resolution_y, r.filepath = old
        for f in folder.iterdir():
            f.unlink()
        folder.rmdir()
