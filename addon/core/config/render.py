"""Render options: the one home of what a probe render may be asked for.

Scan configs (``[render]``), the command line, the panel and the scene all use
:class:`RenderOptions`; the Blender side (``addon.scene.render``) maps it onto
Blender's settings and adds nothing of its own.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass, replace

from ..errors import InputError, check_number, check_whole
from ..optics.sensor import MAX_SHUTTER_FRAMES

ENGINES = ("cycles", "eevee", "raycast")
GPU_BACKENDS = ("OPTIX", "CUDA", "HIP", "ONEAPI", "METAL")
# "GPU": the first backend the machine has, in GPU_BACKENDS' order; a backend by name: that one only.
DEVICES = ("CPU", "GPU") + GPU_BACKENDS
PIXEL_FILTERS = ("BOX", "GAUSSIAN", "BLACKMAN_HARRIS")
LASERS = ("gobo", "spot", "slit")
# Each engine's laser unless one is chosen: Eevee ignores the gobo's node tree, and the
# spot model gives it the same Gaussian line (addon/core/optics/laser_profile.py).
DEFAULT_LASER = {"cycles": "gobo", "eevee": "spot", "raycast": "gobo"}


def laser_engine_mismatch(engine: str, laser: str) -> str | None:
    """Why ``laser`` cannot render in ``engine`` (one sentence naming the laser to use), or None."""
    if engine == "eevee" and laser == "gobo":
        return "the gobo laser does not render in Eevee (it ignores light node trees); use the spot laser " \
               "(the same Gaussian line) or the slit with Eevee"
    if engine == "raycast" and laser != "gobo":
        return f"the raycast engine computes the gobo laser's line; the {laser} laser needs Cycles or Eevee"
    if engine == "cycles" and laser == "spot":
        return "the spot laser is Eevee's line: Cycles samples one of its five lights per path, so it renders " \
               "as noise; use the gobo laser (the same line) with Cycles"
    return None


@dataclass(frozen=True)
class RenderOptions:
    """engine: cycles | eevee | raycast (Cycles' image under ideal conditions, by Embree ray
    casting: see addon/core/optics/raycast.py and :func:`raycast_mismatch`); device: CPU, GPU or a GPU backend by name; samples per pixel;
    pixel filter and its width (px; at 1 sample, each pixel is point-sampled whatever the filter;
    Cycles' BOX is 1 px wide whatever its width, so with more samples it takes width 1); bounces (0 for
    diffuse scenes); ambient: world light strength (0 = dark); laser: gobo (Cycles' smooth
    Gaussian line), spot (the same line from squeezed spot lights, for Eevee) or slit (the
    paper's point light behind an aperture); laser_peak: the
    line's peak as a fraction of full scale (the image's size is the probe's sensor:
    ``Probe.with_resolution``, or a config's resolution override); persistent_data: keep
    Cycles' scene between frames; motion_blur_shutter:
    fraction of a frame the shutter is open (0: none); threads: render threads (None: all)."""

    engine: str = "cycles"
    device: str = "CPU"
    samples: int = 1
    pixel_filter: str = "BOX"
    filter_width_px: float = 0.01
    bounces: int = 0
    ambient: float = 0.0
    laser: str = "gobo"
    laser_peak: float = 0.5
    persistent_data: bool = True
    motion_blur_shutter: float = 0.0
    threads: int | None = None

    def __post_init__(self) -> None:
        for name, value, allowed in (("render engine", self.engine, ENGINES), ("render device", self.device, DEVICES),
                                     ("pixel filter", self.pixel_filter, PIXEL_FILTERS), ("laser", self.laser, LASERS)):
            if value not in allowed:
                raise InputError(f"{name} {value!r} is not one of: {', '.join(allowed)}")
        check_whole(self.samples, "samples", 1, 65536)
        check_number(self.filter_width_px, "filter width (px)", 0.01, 10)
        check_whole(self.bounces, "bounces", 0, 64)
        check_number(self.ambient, "ambient", 0, 100)
        if isinstance(self.laser_peak, bool) or not isinstance(self.laser_peak, numbers.Real) \
                or not 0 < self.laser_peak <= 1e3:
            raise InputError(f"laser peak must be a number in (0, 1000] (fractions of full scale), got "
                             f"{self.laser_peak!r}")
        check_number(self.motion_blur_shutter, "motion blur shutter (frames)", 0, MAX_SHUTTER_FRAMES)
        if self.engine == "cycles" and self.pixel_filter == "BOX" and self.samples > 1 and self.filter_width_px != 1.0:
            # Cycles' box filter is one pixel wide whatever its width says: at 16 samples a width
            # of 0.5 (or 0.01, "point samples") gave the very images of a 1 px box.
            raise InputError(f"Cycles' box pixel filter is one pixel wide whatever its width: at {self.samples} samples "
                             f"it averages each whole pixel, not {self.filter_width_px:g} px of it; give filter width "
                             f"1 px for that, 1 sample for a point sample, or a GAUSSIAN or BLACKMAN_HARRIS filter for "
                             f"another width")
        if not isinstance(self.persistent_data, bool):
            raise InputError(f"persistent data must be True or False, got {self.persistent_data!r}")
        if self.threads is not None:
            check_whole(self.threads, "render threads (or None: all cores)", 1, 1024)


def raycast_mismatch(settings: RenderOptions, material: str, hide_robot: bool = True) -> str | None:
    """Why the raycast engine would not give what Cycles gives for these settings (one sentence
    naming what to change), or None. It computes Cycles' image under the paper's ideal
    conditions only: the gobo laser the only light, diffuse surfaces, no bounces, one point
    sample per pixel, no motion blur, the robot left out."""
    from ..optics.surfaces import DIFFUSE_SURFACES

    why = laser_engine_mismatch("raycast", settings.laser)
    if why:
        return why
    if settings.bounces > 0:
        return f"{settings.bounces} light bounces need light transport: set bounces = 0 or use engine cycles"
    if settings.ambient > 0:
        return f"ambient light {settings.ambient:g} needs light transport: set ambient = 0 or use engine cycles"
    if settings.motion_blur_shutter > 0:  # before the samples: motion blur brings its own
        return "motion during the exposure needs engine cycles"
    # (at one sample Cycles' box, one pixel wide whatever its width, takes the same point)
    if settings.samples != 1 or (settings.pixel_filter != "BOX" and settings.filter_width_px > 0.01):
        return (f"it samples each pixel once at its centre; {settings.samples} samples with a "
                f"{settings.filter_width_px:g} px filter (a sensor that integrates its pixels) need engine cycles")
    if material not in DIFFUSE_SURFACES:
        return f"the {material} surface is not diffuse ({', '.join(DIFFUSE_SURFACES)} are): use engine cycles"
    if not hide_robot:
        return "it leaves the robot out of the probe images: set leave_out.hide_robot = true or use engine cycles"
    return None


def box_width(engine: str, pixel_filter: str, samples: int, width: float) -> float:
    """The filter width a render takes: Cycles' box is one pixel wide whatever its width, which
    shows above one sample (at one, a box of any width takes the same point)."""
    return 1.0 if engine == "cycles" and pixel_filter == "BOX" and samples > 1 else width


def with_sensor(settings, sensor):
    """``settings`` (a RenderOptions) with the sensor model's render-side effects: pixel
    area integration (box filter of one pixel, enough samples to fill it) and motion
    during the exposure (the shutter open for exposure × frame rate of each frame)."""
    samples, pixel_filter, width = settings.samples, settings.pixel_filter, settings.filter_width_px
    if sensor.integrate_pixels:
        samples, pixel_filter, width = max(samples, 16), "BOX", 1.0
    shutter = sensor.shutter_fraction if sensor.motion_blur else 0.0
    if shutter > 0:
        samples = max(samples, 16)
    width = box_width(settings.engine, pixel_filter, samples, width)
    return replace(settings, samples=samples, pixel_filter=pixel_filter, filter_width_px=width,
                   motion_blur_shutter=shutter)
