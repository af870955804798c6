"""The realistic sensor: what a real probe camera makes of the light the renderer computes.

The renderer gives linear irradiance per pixel (1.0 = the ideal mode's full scale).
The sensor model turns it into digital numbers, each effect switchable:

- **optics** (before the sensor): defocus blur and lens distortion. Defocus is a
  Gaussian whose σ follows the thin-lens blur circle for the depth each sensor
  row sees on the laser plane: c = A·f·|z − z_f| / (z·(z_f − f)), A = f/N, taken as
  σ = c/2.355 (a Gaussian of that full width). Distortion is Brown–Conrady in
  OpenCV's form (k1, k2, p1, p2, k3), applied so that ``cv2.undistortPoints``
  with the same coefficients removes it; the pipeline does that when the probe
  is "calibrated".
- **speckle**: the laser line on a rough surface is coherent light; through the
  camera lens it forms subjective speckle with grains of about
  d = 2.44·λ·(1 + M)·N on the sensor (M = f/(z − f), the magnification at depth z),
  i.e. d / pitch pixels. Modelled as a complex Gaussian field, low-passed by a
  disc (the pupil) of that size, squared (fully developed speckle: exponential
  intensity, contrast 1), averaged over each pixel's area (grains much smaller
  than a pixel: Goodman's gamma law for integrated speckle), and multiplied onto
  the laser contrast (not the ambient). A fresh pattern per frame: the probe
  moves more than a grain between frames.
- **the chip**: the probe's pixel count is a simulation choice, the optics are
  not: the chip keeps its physical width (``sensor_width_mm``, default a 1/2"
  format's 6.4 mm), so 160 columns are 40 µm pixels and 1280 are 5 µm ones, and
  the lens (f = f_px × pitch, 13 mm for the default probe) is the same real lens
  at every resolution. Defocus and speckle follow from that lens.
- **exposure and saturation**: electrons = irradiance × ``electrons_per_unit`` ×
  exposure / 1 ms; the full well clips; gain and quantisation to ``bit_depth``.
  Auto-exposure sets the exposure so the line's peak lands at a target fraction.
- **noise**: photon shot noise (Poisson on the electrons), read noise (Gaussian,
  electrons), a dark offset (DN) and fixed-pattern gain (photo-response
  non-uniformity, one map per camera, fixed for the sensor); all seeded.

The output is DN / (2^bits − 1) as float32, so 1.0 is full scale and clipping is at 1.0.
Pixel integration and motion during exposure happen in the renderer (area
sampling; Cycles motion blur) and are switched from here too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from ..errors import InputError
from .probe import Probe

BIT_DEPTHS = (8, 10, 12, 16)
# With motion blur the shutter stays open for exposure x frame rate of a frame, at most this
# share: the cell keys each frame's motion half of it either side of the frame
# (scene.render.EXPOSURE_KEY_FRAMES), short of the next frame's keys across a jump between
# path entries.
MAX_SHUTTER_FRAMES = 0.98
EFFECTS = ("integrate_pixels", "saturate", "noise", "speckle", "defocus", "motion_blur")  # the switches (and distortion)


@dataclass(frozen=True)
class SensorModel:
    """Everything off (``SensorModel()``) is the ideal sensor of the paper's simulation."""

    integrate_pixels: bool = False   # renderer: area sampling (box filter 1 px, >= 16 samples)
    saturate: bool = False           # exposure, full-well clipping, gain, quantisation
    noise: bool = False              # shot noise, read noise, dark offset, fixed-pattern gain
    speckle: bool = False
    defocus: bool = False
    distortion: tuple = ()           # (k1, k2, p1, p2[, k3]); empty: none
    undistort: bool = True           # detections undistorted (by the true lens, or a calibration's)
    motion_blur: bool = False        # renderer: the probe moves during the exposure

    exposure_ms: float = 1.0
    auto_exposure: bool = False
    target_peak: float = 0.7         # auto-exposure: line peak as a fraction of the clip level (exposure_for)
    gain: float = 1.0
    bit_depth: int = 12
    full_well_e: float = 10000.0
    electrons_per_unit: float = 6000.0  # electrons at 1 ms for irradiance 1.0 (ideal full scale)
    read_noise_e: float = 5.0
    dark_offset_dn: float = 16.0
    prnu: float = 0.01               # fixed-pattern gain variation, standard deviation
    sensor_width_mm: float = 6.4     # the chip's width along the line (1/2" format); sets the pixel pitch
    pixel_pitch_um: float | None = None  # None: sensor_width_mm / columns (the optics stay those of a real lens)
    f_number: float = 8.0
    focus_mm: float | None = None    # depth (along the camera axis) in focus; None: balanced over the range
    wavelength_nm: float = 650.0
    frame_rate_hz: float = 100.0     # motion blur: shutter fraction = exposure × frame rate
    seed: int = 1
    _cache: dict = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self) -> None:
        if self.bit_depth not in BIT_DEPTHS:
            raise InputError(f"bit_depth must be one of {BIT_DEPTHS}, got {self.bit_depth}")
        for name in ("exposure_ms", "gain", "full_well_e", "electrons_per_unit", "sensor_width_mm", "f_number",
                     "wavelength_nm", "frame_rate_hz") + tuple(
                         k for k in ("pixel_pitch_um", "focus_mm") if getattr(self, k) is not None):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise InputError(f"sensor {name} must be a positive number, got {v!r}")
        for name in ("read_noise_e", "dark_offset_dn", "prnu"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise InputError(f"sensor {name} must be zero or positive, got {v!r}")
        if not 0 < self.target_peak <= 1:
            raise InputError(f"target_peak must be in (0, 1], got {self.target_peak}")
        if len(self.distortion) not in (0, 4, 5) or not all(math.isfinite(float(c)) for c in self.distortion):
            raise InputError(f"distortion must be 4 or 5 finite coefficients (k1, k2, p1, p2[, k3]), "
                             f"got {list(self.distortion)}")
        if self.motion_blur and self.shutter_fraction > MAX_SHUTTER_FRAMES:
            raise InputError(f"exposure {self.exposure_ms:g} ms is longer than {MAX_SHUTTER_FRAMES:g} of a frame at "
                             f"{self.frame_rate_hz:g} Hz: with motion blur the shutter stays open for at most "
                             f"{MAX_SHUTTER_FRAMES:g} of a frame ({MAX_SHUTTER_FRAMES * 1000.0 / self.frame_rate_hz:.4g} "
                             f"ms at this rate)")

    # -- switches -------------------------------------------------------------------------
    @property
    def ideal(self) -> bool:
        return not (any(getattr(self, name) for name in EFFECTS) or self.distortion)

    @property
    def changes_images(self) -> bool:
        """True when :meth:`apply` changes a rendered image (the other effects act in the renderer)."""
        return bool(self.saturate or self.noise or self.speckle or self.defocus or self.distortion)

    @property
    def clips(self) -> bool:
        return self.saturate

    @property
    def clip_level(self) -> float:
        """The image value (fraction of full scale) a clipped pixel reads: the ADC's top, or the
        full well where the gain puts it lower (gain 0.5: half scale, plus the dark offset). The
        detector flags lines that reach it (it took 1.0 whatever the gain, and a line clipped
        at half scale passed as good, off by a quarter pixel with a σ of 0.016 px)."""
        top = 2 ** self.bit_depth - 1
        well = self.full_well_e * self.gain * self._dn_per_e() + (self.dark_offset_dn if self.noise else 0.0)
        return float(min(top, round(well)) / top)

    @property
    def shutter_fraction(self) -> float:
        """The share of a frame the shutter is open (rounded to 12 decimals: 9.8 ms at 100 Hz is 0.98)."""
        return round(self.exposure_ms * self.frame_rate_hz / 1000.0, 12)

    def dist_coeffs(self) -> np.ndarray:
        d = list(self.distortion) + [0.0] * (5 - len(self.distortion))
        return np.array(d, dtype=np.float64) if self.distortion else np.zeros(5)

    # -- geometry helpers ------------------------------------------------------------------
    def pitch_um(self, probe: Probe) -> float:
        """Pixel pitch: as set, or the chip width shared by the probe's columns."""
        return self.pixel_pitch_um if self.pixel_pitch_um is not None else 1e3 * self.sensor_width_mm / probe.cols_px

    def focal_mm(self, probe: Probe) -> float:
        return probe.f_px * self.pitch_um(probe) * 1e-3

    def row_depths_mm(self, probe: Probe, rows: np.ndarray) -> np.ndarray:
        """Distance along the optical axis of the laser-plane point each sensor row sees (centre column)."""
        cy = probe.principal_point[1]
        psi = probe.phi_rad - np.arctan((cy - rows) / probe.f_px)
        z = probe.a_mm / np.tan(psi) + probe.b_mm
        return (z - probe.b_mm) * math.cos(probe.phi_rad) + probe.a_mm * math.sin(probe.phi_rad)

    def focus_depth_mm(self, probe: Probe) -> float:
        """The depth in focus: as set, or where the blur at the near and far ends of the
        range is equal (the harmonic mean of the depths the first and last rows see)."""
        if self.focus_mm is not None:
            return self.focus_mm
        ends = self.row_depths_mm(probe, np.array([0.0, probe.rows_px - 1.0]))
        return float(2.0 / np.sum(1.0 / ends))

    def blur_sigma_px(self, probe: Probe, depth_mm) -> np.ndarray:
        """Defocus σ (px) at object distance ``depth_mm`` (thin lens, focused at ``focus_mm``)."""
        f = self.focal_mm(probe)
        zf = self.focus_depth_mm(probe)
        if zf <= f:
            given = "[sensor] focus_mm" if self.focus_mm is not None else \
                "the depth in focus (where the blur at both ends of the range is equal: [sensor] focus_mm is not set)"
            raise InputError(f"defocus: {given} {zf:g} mm must lie beyond the lens's focal length ({f:.4g} mm, from "
                             f"[sensor] pixel_pitch_um {self.pitch_um(probe):g} and the probe's field of view): a smaller "
                             f"pixel pitch or a farther focus")
        z = np.asarray(depth_mm, dtype=np.float64)
        c_mm = (f / self.f_number) * f * np.abs(z - zf) / (z * (zf - f))
        return c_mm / (self.pitch_um(probe) * 1e-3) / 2.355

    def spread_px(self, probe: Probe) -> int:
        """Rows beyond the rendered line that the optics spread or move its light over: three σ
        of the largest defocus blur on the sensor, plus the most lens distortion moves a pixel
        along the columns (0 without either). A render of a band of rows around the line needs
        them, or the blur's tail is cut off on one side and a distorted line falls outside."""
        rows = 0.0
        if self.defocus:
            sigma = self.blur_sigma_px(probe, self.row_depths_mm(probe, np.array([0.0, probe.rows_px - 1.0])))
            rows += 3.0 * float(np.max(sigma))
        if self.distortion:
            rows += self.distortion_shift_px(probe)
        return int(math.ceil(rows))

    def band_pad_px(self, probe: Probe) -> int:
        """Rows a band render must hold beyond the rows read from it for those rows to be what
        a full frame gives them: the reach of the defocus blur's kernel (OpenCV's, 4 σ of the
        largest blur, for float images) and then of the lens distortion's resampling (0 for a
        sensor with neither)."""
        rows = 0
        if self.defocus:
            sigma = self.blur_sigma_px(probe, self.row_depths_mm(probe, np.array([0.0, probe.rows_px - 1.0])))
            rows += int(math.ceil(4.0 * float(np.max(sigma)))) + 1
        if self.distortion:
            rows += int(math.ceil(self.distortion_shift_px(probe))) + 1
        return rows

    def distortion_shift_px(self, probe: Probe) -> float:
        """The most lens distortion moves a point along its column where the pinhole and the lens
        both put it on the sensor (px; 0 without distortion): the most over a grid of pixels 2 px
        apart and the sensor's edges, plus a pixel for what lies between them (where the ideal
        point leaves the sensor the grid can miss the most by a fraction of a pixel). A pixel
        whose ideal point lies off the sensor shows nothing rendered, so its shift does not
        matter."""
        if not self.distortion:
            return 0.0
        us = np.unique(np.append(np.arange(0.0, probe.cols_px, 2.0), probe.cols_px - 1.0))
        vs = np.unique(np.append(np.arange(0.0, probe.rows_px, 2.0), probe.rows_px - 1.0))
        u, v = (a.ravel() for a in np.meshgrid(us, vs))
        u_ideal, v_ideal = self.undistort_pixels(probe, u, v)
        seen = (u_ideal >= 0) & (u_ideal <= probe.cols_px - 1) & (v_ideal >= 0) & (v_ideal <= probe.rows_px - 1)
        return float(np.max(np.abs(v_ideal - v)[seen], initial=0.0)) + 1.0

    def speckle_grain_px(self, probe: Probe, depth_mm) -> np.ndarray:
        """Mean speckle grain diameter on the sensor (px) at object distance ``depth_mm``."""
        f = self.focal_mm(probe)
        M = f / (np.asarray(depth_mm, dtype=np.float64) - f)
        return 2.44 * self.wavelength_nm * 1e-6 * (1 + M) * self.f_number / (self.pitch_um(probe) * 1e-3)

    # -- the model ---------------------------------------------------------------------------
    def exposure_for(self, peak_irradiance: float) -> float:
        """Exposure (ms) that puts a line of this peak irradiance at ``target_peak`` of the most
        the sensor reads (its clip level: the full well, or the ADC's range where a gain above 1
        reaches it first; with a gain below 1 that is under full scale). With motion blur, at
        most the longest shutter a frame allows (the blur itself was rendered for exposure_ms)."""
        if peak_irradiance <= 0:
            return self.exposure_ms
        full_scale_e = min(self.full_well_e, (2 ** self.bit_depth - 1) / max(self.gain * self._dn_per_e(), 1e-12))
        exposure = self.target_peak * full_scale_e / (peak_irradiance * self.electrons_per_unit)
        if self.motion_blur:  # no exposure outlasts the frame it is taken in
            exposure = min(exposure, MAX_SHUTTER_FRAMES * 1000.0 / self.frame_rate_hz)
        return exposure

    def _dn_per_e(self) -> float:
        # Gain 1 maps the full well onto the ADC's range.
        return (2 ** self.bit_depth - 1) / self.full_well_e

    def apply(self, image: np.ndarray, probe: Probe, camera: int, frame: int, row0: int = 0,
              exposure_ms: float | None = None) -> np.ndarray:
        """The sensor's image (H, W, 3) float32 in full-scale units, from a linear render.

        ``row0``: the first sensor row the image holds (band renders). Every random
        field is drawn for the whole sensor from (seed, camera, frame) and cropped, so a
        pixel gets the same noise and speckle whatever band was rendered.
        ``exposure_ms`` overrides the configured exposure; with auto-exposure and no
        override, the exposure comes from this frame's light as it reaches the sensor
        (speckle and optics included): see :func:`metered_peak`.
        """
        img = np.asarray(image, dtype=np.float32)
        H, W = img.shape[:2]
        band = slice(row0, row0 + H)
        rows = np.arange(row0, row0 + H, dtype=np.float64)
        rng = np.random.default_rng([self.seed, camera, frame])
        speckle = speckle_pattern(probe.rows_px, probe.cols_px, self._grain(probe), rng)[band] if self.speckle else None
        shot = rng.standard_normal((probe.rows_px, probe.cols_px, 3))[band] if self.noise else None
        read = rng.standard_normal((probe.rows_px, probe.cols_px, 3))[band] if self.noise else None
        if speckle is not None:
            ambient = np.minimum(img[:, :, 1], img[:, :, 2])  # the laser is red: G and B carry only the ambient
            img = img.copy()
            img[:, :, 0] = ambient + (img[:, :, 0] - ambient) * speckle
        if self.defocus:
            img = self._defocus(img, probe, rows)
        if self.distortion:
            img = self._distort(img, probe, row0)
        if not (self.saturate or self.noise):
            return img
        if exposure_ms is None and self.auto_exposure:
            exposure_ms = self.exposure_for(metered_peak(img))
        t = self.exposure_ms if exposure_ms is None else exposure_ms
        electrons = img.astype(np.float64) * self.electrons_per_unit * t
        if self.noise:
            # Shot noise in its Gaussian form (exact in mean and variance; the counts here are large).
            electrons = np.maximum(electrons, 0.0)
            electrons = electrons + np.sqrt(electrons) * shot
            electrons *= self._prnu_map(probe, camera)[band, :, None]
            electrons += self.read_noise_e * read
        if self.saturate:
            electrons = np.minimum(electrons, self.full_well_e)
        dn = electrons * self.gain * self._dn_per_e()
        if self.noise:
            dn += self.dark_offset_dn
        top = 2 ** self.bit_depth - 1
        if self.saturate:
            dn = np.clip(np.round(dn), 0, top)
        return (dn / top).astype(np.float32)

    def _grain(self, probe: Probe) -> float:
        """Speckle grain (px) at the middle of the range (it changes by M, a few %, across it)."""
        z = 0.5 * sum(probe.z_range_mm)
        depth = (z - probe.b_mm) * math.cos(probe.phi_rad) + probe.a_mm * math.sin(probe.phi_rad)
        return float(self.speckle_grain_px(probe, depth))

    def _prnu_map(self, probe: Probe, camera: int) -> np.ndarray:
        # The seed and the spread in the key: dataclasses.replace() hands the copy this cache
        key = ("prnu", camera, probe.rows_px, probe.cols_px, self.seed, self.prnu)
        if key not in self._cache:
            rng = np.random.default_rng([self.seed, 1000 + camera])
            self._cache[key] = 1.0 + self.prnu * rng.standard_normal((probe.rows_px, probe.cols_px))
        return self._cache[key]

    def _defocus(self, img, probe, rows) -> np.ndarray:
        """Each sensor row's light spread by the blur of the depth that row sees on the laser
        plane: a few blur levels, each row's light shared between the two nearest. The light
        is spread from where it comes (each source row its own blur), not gathered into each
        row by that row's blur: where the blur changes across the line's few rows (f/1), the
        gathered line came out lopsided and every point 290 µm deep; spread, a line at one
        depth stays symmetric and its light is kept."""
        sigma = self.blur_sigma_px(probe, self.row_depths_mm(probe, rows))
        # The levels from the whole sensor's blur, so that a row is blurred alike whichever band
        # of rows was rendered (from the band's own, two bands gave a row different shares).
        every = self.blur_sigma_px(probe, self.row_depths_mm(probe, np.arange(probe.rows_px, dtype=np.float64)))
        levels = np.unique(np.round(np.linspace(float(np.min(every)), float(np.max(every)), 6), 3))
        if len(levels) == 1:
            return img if levels[0] < 0.05 else cv2.GaussianBlur(img, (0, 0), float(levels[0]),
                                                                 borderType=cv2.BORDER_REPLICATE)
        idx = np.clip(np.searchsorted(levels, sigma) - 1, 0, len(levels) - 2)
        w = np.clip((sigma - levels[idx]) / np.maximum(levels[idx + 1] - levels[idx], 1e-9), 0.0, 1.0)
        out = np.zeros_like(img)
        shape = (-1,) + (1,) * (img.ndim - 1)  # a weight per row, over the columns (and channels)
        for k, s in enumerate(levels):
            share = np.where(idx == k, 1.0 - w, 0.0) + np.where(idx + 1 == k, w, 0.0)
            if not share.any():
                continue
            part = (img * share.reshape(shape)).astype(img.dtype, copy=False)
            # (The band's edge rows continued outward: mirrored, a line near the edge gained a twin.)
            out += part if s < 0.05 else cv2.GaussianBlur(part, (0, 0), float(s), borderType=cv2.BORDER_REPLICATE)
        return out

    def _distort(self, img, probe, row0) -> np.ndarray:
        """Resample so a point at undistorted pixel p appears at its distorted position."""
        H, W = img.shape[:2]
        K = probe.K
        u, v = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(row0, row0 + H, dtype=np.float64))
        pts = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
        # Each output (distorted) pixel shows the undistorted point it comes from.
        src = cv2.undistortPoints(pts, K, self.dist_coeffs(), P=K).reshape(H, W, 2).astype(np.float32)
        src[:, :, 1] -= row0
        return cv2.remap(img, src[:, :, 0], src[:, :, 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)

    def undistort_pixels(self, probe: Probe, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Detected (distorted) pixel positions -> where an ideal pinhole camera would see them."""
        if not self.distortion or len(u) == 0:
            return u, v
        pts = np.stack([u, v], axis=1).reshape(-1, 1, 2).astype(np.float64)
        out = cv2.undistortPoints(pts, probe.K, self.dist_coeffs(), P=probe.K).reshape(-1, 2)
        return out[:, 0], out[:, 1]


METER_PERCENTILE = 95.0


def metered_peak(img: np.ndarray) -> float:
    """The line peak auto-exposure aims at: the 95th percentile of the columns' laser peaks
    (red over ambient) among the lit columns (peak above 5 % of the brightest). A few
    speckle or glint hot spots may clip, as on a real camera; the rest of the line does not."""
    contrast = img[..., 0] - np.minimum(img[..., 1], img[..., 2])
    peaks = contrast.max(axis=0)
    lit = peaks > 0.05 * peaks.max()
    return float(np.percentile(peaks[lit], METER_PERCENTILE)) if peaks.max() > 0 else 0.0


def speckle_pattern(H: int, W: int, grain_px: float, rng: np.random.Generator, oversample: int | None = None
                    ) -> np.ndarray:
    """Fully developed speckle intensity (mean 1) with mean grain diameter ``grain_px``, averaged over pixels.

    Grains the sub-sampling resolves: a complex Gaussian field is low-passed by a disc
    pupil in the frequency domain whose cut-off makes the intensity's grain
    ``grain_px`` (Airy core: diameter 2.44 λN for a pupil of radius 1/(2λN)); the
    squared magnitude is box-averaged over each pixel (``oversample``² sub-samples),
    which lowers the contrast as grains shrink.

    Grains too small for that (below 2.5 sub-samples): each pixel sums many
    independent grains, which Goodman's integrated-speckle model gives as a gamma
    variable of M = 1 + A_pixel / A_c degrees of freedom (A_c = (4/π)(λN)², the
    correlation area of a circular pupil, i.e. (4/π)(grain/2.44)²), contrast 1/√M,
    independent between pixels. The two agree within 15 % where they meet.
    """
    s = oversample or (4 if H * W <= 400_000 else 2)
    if grain_px * s < 2.5:
        M = 1.0 + 1.0 / ((4.0 / math.pi) * (grain_px / 2.44) ** 2)
        return rng.gamma(M, 1.0 / M, size=(H, W)).astype(np.float32)
    h, w = H * s, W * s
    field = rng.standard_normal((h, w)) + 1j * rng.standard_normal((h, w))
    fy = np.fft.fftfreq(h)[:, None]
    fx = np.fft.fftfreq(w)[None, :]
    # The pupil passes spatial frequencies up to D/(2λz) = 1/(2λN); the intensity's grain (the
    # Airy core, 2.44λN) is then ``grain_px``: radius 1.22/grain, in cycles per sub-sample.
    cutoff = 1.22 / (grain_px * s)
    pupil = (fx * fx + fy * fy) <= cutoff ** 2
    speck = np.abs(np.fft.ifft2(np.fft.fft2(field) * pupil)) ** 2
    speck /= speck.mean()
    return speck.reshape(H, s, W, s).mean(axis=(1, 3)).astype(np.float32)
