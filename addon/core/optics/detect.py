"""Laser-line detection: for every sensor column, the sub-pixel row of the line.

Input: an image (H, W, 3) RGB or (H, W, 4) RGBA or (H, W) grey, as uint8, uint16
or float (linear, 1.0 = full scale). The laser is red on a grey workpiece, so the
signal is the laser contrast R − (G + B)/2 (the intensity itself for grey images).
Rows run along the triangulation direction, columns along the line; OpenCV pixel
convention (pixel centres at integers).

Methods (``detect_line(image, method=...)``):

- ``threshold``: the paper's. Threshold the HSV saturation (and value) of the
  image, take the centre of the run of lit pixels in each column. Half-pixel
  resolution at best.
- ``cog``: centre of gravity of the contrast above a fraction of the column's peak.
- ``gauss``: three-point Gaussian fit (a parabola through the logarithms of the
  peak sample and its two neighbours): exact on a point-sampled Gaussian line.
  For noisy images the column profile is first smoothed along the column with a
  Gaussian matched to the line's width, which averages the noise out; on a line
  only a pixel or two wide the sampled smoothing is no longer exactly Gaussian and
  costs a few hundredths of a pixel, so noise-free images are better read unsmoothed
  (``smoothing_px=0``).
- ``steger``: Hessian ridge detection. OpenCV smooths the contrast with a
  Gaussian; the Hessian at each column's peak must show a ridge (strongly
  negative curvature across the line); the centre is where the derivative of the
  smoothed profile vanishes, found by Newton steps on the continuous
  Gaussian-derivative response (exact to rounding instead of Steger's one-step
  Taylor estimate, whose bias reaches a few hundredths of a pixel on narrow lines).

Every method reports per column a code (:class:`LineCode`). A column with a
second, separated peak (a reflection) is AMBIGUOUS and gets no position: the two
are never averaged. Everything is vectorised over columns.

Shape of the line and the centre's uncertainty. The laser's profile across the line
is a Gaussian; near the peak its logarithm is a parabola whose curvature gives the
profile's own width σ₃ (from the peak sample and its two neighbours). The line's
width in the image hardly depends on depth (the beam widens with range as the
image shrinks), so the image's median σ₃ is what a whole, unobstructed line looks
like here. A column whose line is cut across its width (an edge of the part, a
ridge hiding part of the strip) is narrower than that: its centre is no longer on
the laser plane, and it is coded EDGE (``min_width_ratio``). For the rest, the two
flanks of the profile each give the centre if the width is the image's, and the
two answers differ by |σ_med²/σ₃² − 1| pixels: half of that, the shift the profile's
asymmetry shows (a strip bent across the line by the surface's curvature images as a
skewed Gaussian whose peak moves by μ₃ / (3·var)), and the image noise's effect on the
fit make up the centre's uncertainty ``sigma_px``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

import cv2
import numpy as np

from ..errors import InputError

METHODS = ("threshold", "cog", "gauss", "steger")
STEGER_MIN_SIGMA = 1.0
NARROW_LINE_SIGMA_PX = 0.8  # below this line σ, auto smoothing is off (see _smoothing)


class LineCode(IntEnum):
    OK = 0
    NO_LINE = 1      # no contrast above the threshold
    SATURATED = 2    # the line's peak is clipped: every detector is biased
    AMBIGUOUS = 3    # two separated peaks (e.g. a reflection): rejected, not averaged
    TOO_WIDE = 4     # wider than max_width_px: defocused, grazing, or not a laser line
    BAD_PIXELS = 5   # NaN or inf in the column
    EDGE = 6         # the peak on the first or last row, or the line cut beside it: cannot be localised


@dataclass(frozen=True)
class DetectParams:
    """Detector settings; contrast levels are fractions of full scale.

    min_peak : least peak contrast that counts as a line
    second_peak_ratio : a second peak at least this fraction of the main one, outside
        the exclusion band around it, makes the column AMBIGUOUS
    exclusion_px : half-width of that band (default: max(4, 2 × measured FWHM))
    max_width_px : wider lines (FWHM) are TOO_WIDE
    max_width_ratio : columns wider than this many times the image's median line width
        are TOO_WIDE (None: off). Where the surface turns away from the laser across the
        line (grazing along the scan direction) the lit strip widens on the part and its
        centre leaves the laser plane; its image widens with it.
    min_width_ratio : columns whose line is narrower than this many times the image's
        median are EDGE (None: off). An edge of the part that cuts the line across its
        width leaves part of the line's profile lit: narrower than the whole line, and its
        centre off the laser plane, so its point would float beside the part. The width
        compared is the profile's own, σ₃ from the curvature at the peak (FWHM for a
        flat-topped line, which has no curvature there).
    window_px : half-window around the peak used for widths and the centre of gravity
    cog_level : the centre of gravity uses contrast above this fraction of the peak
    saturation : level counted as clipped, as a fraction of full scale (default 1.0,
        i.e. 255 for uint8, 65535 for uint16, 1.0 for float images)
    smoothing_px : σ (pixels) of the smoothing used by ``gauss`` (along columns) and
        ``steger`` (2-D). None: matched to the line, σ = median FWHM / 2.355, or none for
        a Gaussian line narrower than NARROW_LINE_SIGMA_PX; 0: no smoothing for ``gauss``
    flat_top : the line's profile is flat-topped with hard edges (the slit laser): it
        is always smoothed (at least 0.8 px), as a flat top has no peak to fit
    hsv_saturation, hsv_value : thresholds of the ``threshold`` method (0..1)
    """

    min_peak: float = 0.05
    second_peak_ratio: float = 0.25
    exclusion_px: float | None = None
    max_width_px: float = 25.0
    max_width_ratio: float | None = None
    min_width_ratio: float | None = None
    window_px: int = 8
    cog_level: float = 0.5
    saturation: float | None = None
    smoothing_px: float | None = None
    flat_top: bool = False
    hsv_saturation: float = 0.3
    hsv_value: float = 0.05


@dataclass
class LineDetection:
    """Per column of the sensor (W entries each).

    col : (W,) int, column index u
    row : (W,) float, sub-pixel row v of the line centre (NaN where code != OK)
    peak : (W,) float, peak laser contrast (fraction of full scale)
    width : (W,) float, full width at half maximum in pixels (NaN if unknown)
    code : (W,) uint8, a LineCode per column
    peak_row : (W,) int, sensor row of each column's brightest pixel, whatever its code
               (None where a detection was made up from given rows)
    sigma_px : (W,) float, uncertainty of ``row`` in pixels (NaN where code != OK; None
               where a detection was made up from given rows: unknown)
    """

    col: np.ndarray
    row: np.ndarray
    peak: np.ndarray
    width: np.ndarray
    code: np.ndarray
    method: str
    shape: tuple[int, int]
    peak_row: np.ndarray | None = None
    sigma_px: np.ndarray | None = None

    @property
    def valid(self) -> np.ndarray:
        return self.code == LineCode.OK

    def counts(self) -> dict[str, int]:
        """Number of columns per code, by name."""
        n = np.bincount(np.asarray(self.code, dtype=np.intp), minlength=len(LineCode))
        return {c.name: int(n[c]) for c in LineCode if n[c]}


CUT_SHARE = 1e-5  # a peak's neighbour below this share of it is no light: the line is cut (gauss)


# -- small helpers (numpy's clip and median cost more in their argument checks than in their work
# on a line's few hundred columns, and detection calls them dozens of times a frame) ------------

def _clamp(x, lo, hi):
    """np.clip(x, lo, hi) for numbers and arrays of numbers."""
    return np.minimum(np.maximum(x, lo), hi)


def _median(a: np.ndarray) -> float:
    """np.median of a non-empty 1-D array of finite numbers."""
    n = a.size
    k = n // 2
    if n % 2:
        return float(np.partition(a, k)[k])
    part = np.partition(a, (k - 1, k))
    return float(0.5 * (part[k - 1] + part[k]))


# -- input ------------------------------------------------------------------------------

def _prepare(image) -> tuple[np.ndarray, np.ndarray | None, float]:
    """(contrast (H, W) float32, RGB float32 or None, full-scale factor) from any accepted image."""
    if not isinstance(image, np.ndarray):
        raise InputError(f"image must be a numpy array, got {type(image).__name__}")
    if image.ndim == 3 and image.shape[2] == 4:
        image = image[:, :, :3]
    if not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] == 3)):
        raise InputError(f"image must be (H, W), (H, W, 3) or (H, W, 4), got shape {image.shape}")
    if image.shape[0] < 3 or image.shape[1] < 1:
        raise InputError(f"image needs at least 3 rows and 1 column, got shape {image.shape}")
    kind = image.dtype.kind
    if image.dtype == np.uint8:
        scale = 255.0
    elif image.dtype == np.uint16:
        scale = 65535.0
    elif kind == "f":
        scale = 1.0
    else:
        raise InputError(f"image dtype must be uint8, uint16 or float, got {image.dtype}")
    img = image.astype(np.float32, copy=False)
    if scale != 1.0:
        img = img * np.float32(1.0 / scale)
    if img.ndim == 2:
        return np.ascontiguousarray(img), None, scale
    img = np.ascontiguousarray(img)
    contrast = cv2.transform(img, np.array([[1.0, -0.5, -0.5]], dtype=np.float32))
    return contrast.reshape(img.shape[:2]), img, scale


# -- main entry ---------------------------------------------------------------------------

def detect_line(image, method: str = "gauss", params: DetectParams | None = None,
                row_offset: int = 0) -> LineDetection:
    """Detect the laser line in every column of ``image``; see the module docstring.

    ``row_offset``: the sensor row of the image's first row (a band render). Every
    method finds an integer peak row and a sub-pixel offset from it, and reports
    (peak + row_offset) + offset, so a band gives bit for bit the rows a full
    frame gives. The result's ``shape`` is still the image's."""
    if method not in METHODS:
        raise InputError(f"detection method {method!r} is not one of: {', '.join(METHODS)}")
    if isinstance(row_offset, bool) or not isinstance(row_offset, (int, np.integer)):
        if not (isinstance(row_offset, (float, np.floating)) and float(row_offset).is_integer()):
            raise InputError(f"row_offset must be a whole number of rows, got {row_offset!r}")
    p = params or DetectParams()
    C, rgb, _ = _prepare(image)
    H, W = C.shape
    cols = np.arange(W)

    code = np.zeros(W, dtype=np.uint8)
    finite = np.isfinite(C)
    if not finite.all():
        bad_cols = ~finite.all(axis=0)
        code[bad_cols] = LineCode.BAD_PIXELS
        C = np.where(finite, C, np.float32(0.0))
        if rgb is not None:
            rgb = np.where(np.isfinite(rgb), rgb, np.float32(0.0))

    if method == "threshold":
        return _detect_threshold(C, rgb, p, code, int(row_offset))

    sigma_s = _smoothing(C, p)
    if method == "steger":
        # Below σ ≈ 1 px the sampled, smoothed profile is too coarse for the Hessian.
        sigma_s = max(sigma_s, STEGER_MIN_SIGMA) if p.smoothing_px is None else sigma_s
        S = cv2.GaussianBlur(C, (0, 0), sigma_s)
    elif method == "gauss" and sigma_s > 0:
        S = _smooth_columns(C, sigma_s)
    else:
        S = C
    r = _argmax_rows(S)
    peak = C[r, cols]
    code[(code == 0) & (peak < p.min_peak)] = LineCode.NO_LINE
    code[(code == 0) & ((r == 0) | (r == H - 1))] = LineCode.EDGE

    width = _fwhm(C, r, peak, _width_reach(p, H))
    code[(code == 0) & ~(width <= p.max_width_px)] = LineCode.TOO_WIDE
    code[(code == 0) & _wider_than_the_line(width, code, p)] = LineCode.TOO_WIDE
    shape = width / 2.355 if p.flat_top else _profile_sigma(S, r, cols)
    shape_ok = (code == 0) & np.isfinite(shape)
    shape_median = _median(shape[shape_ok]) if shape_ok.sum() >= 8 else np.nan
    if p.min_width_ratio is not None and np.isfinite(shape_median):
        code[(code == 0) & ~(shape >= p.min_width_ratio * shape_median)] = LineCode.EDGE
    code[(code == 0) & _saturated(C if rgb is None else rgb, r, p)] = LineCode.SATURATED
    code[(code == 0) & _second_peak(S, r, peak if S is C else S[r, cols], width, p)] = LineCode.AMBIGUOUS

    rr = _clamp(r, 1, H - 2)
    if method == "gauss":
        # A neighbour with no light to speak of: the line is cut there (a depth edge), and the
        # three-point fit has nothing to fit on that side. "None to speak of" is below
        # CUT_SHARE of the peak, not 0: a renderer's tail of the Gaussian far beyond the edge
        # (1e-45 in Cycles) is no light either; a whole line's neighbour, a pixel from its peak,
        # is at least that bright down to a line σ of 0.3 px at any sub-pixel phase (the far
        # neighbour of a peak half a pixel off centre gets exp(−1/σ²) of it).
        floor = CUT_SHARE * S[rr, cols]
        cut = (S[rr - 1, cols] <= floor) | (S[rr + 1, cols] <= floor)
        code[(code == 0) & cut] = LineCode.EDGE
    ok = code == 0
    row = np.full(W, np.nan)
    base = (rr + int(row_offset)).astype(np.float64)
    if method == "gauss":
        row[ok] = base[ok] + _log_parabola(S, rr, cols)[ok]
    elif method == "cog":
        row[ok] = (r + int(row_offset)).astype(np.float64)[ok] + _centre_of_gravity(C, r, peak, p)[ok]
    else:
        row[ok] = base[ok] + _steger(C, S, rr, sigma_s)[ok]
    code[ok & ~np.isfinite(row)] = LineCode.NO_LINE
    row[code != 0] = np.nan
    sigma_px = _centre_sigma(C, S, r, cols, shape, shape_median, p)
    sigma_px[code != 0] = np.nan
    return LineDetection(cols, row, peak.astype(np.float64), width, code, method, (H, W), r + int(row_offset),
                         sigma_px)


# -- per-column pieces --------------------------------------------------------------------

def _window(C: np.ndarray, r: np.ndarray, half: int) -> np.ndarray:
    """(2·half + 1, W) samples of each column around row r (edge rows repeated)."""
    H, W = C.shape
    rows = _clamp(r[None, :] + np.arange(-half, half + 1)[:, None], 0, H - 1)
    return C[rows, np.arange(W)[None, :]]


def _width_reach(p: DetectParams, rows: int) -> int:
    """Rows either side of the peak that the width's half-level search looks at: the fitting
    window, or as far as a line of max_width_px reaches (a line 17-25 px wide had no half-level
    crossing within the 8-row window, read infinitely wide, and was rejected as too wide)."""
    reach = p.max_width_px / 2.0 + 1.0 if math.isfinite(p.max_width_px) else rows
    return int(min(rows, max(p.window_px, math.ceil(reach))))


def _fwhm(C, r, peak, half) -> np.ndarray:
    """Full width at half maximum from linear interpolation of the two half-level crossings."""
    win = _window(C, r, half).astype(np.float64)
    level = 0.5 * peak
    widths = np.zeros(C.shape[1])
    for side in (win[half::-1], win[half:]):  # from the peak outwards, each way
        below = side < level[None, :]
        found = below.any(axis=0)
        k = np.argmax(below, axis=0)  # first sample below half, counted from the peak
        k = np.maximum(k, 1)
        cols = np.arange(C.shape[1])
        hi, lo = side[k - 1, cols], side[k, cols]
        frac = np.where(hi > lo, (hi - level) / np.where(hi > lo, hi - lo, 1.0), 0.0)
        widths += np.where(found, k - 1 + frac, np.inf)
    return widths


def _saturated(img, r, p: DetectParams) -> np.ndarray:
    """True where a pixel at or next to the peak reaches the clipping level in any channel."""
    level = 1.0 if p.saturation is None else p.saturation
    H = img.shape[0]
    W = img.shape[1]
    cols = np.arange(W)
    hit = np.zeros(W, dtype=bool)
    for k in (-1, 0, 1):
        rows = _clamp(r + k, 0, H - 1)
        v = img[rows, cols]
        hit |= (v.max(axis=-1) if v.ndim == 2 else v) >= level * (1 - 1e-6)
    return hit


def _argmax_rows(S: np.ndarray) -> np.ndarray:
    """Row of the maximum in each column, (W,) int. OpenCV's reduction is about twice
    as fast as numpy's argmax along axis 0 on large frames."""
    return cv2.reduceArgMax(np.ascontiguousarray(S, dtype=np.float32), 0).ravel().astype(np.intp)


def _second_peak(S, r, peak, width, p: DetectParams) -> np.ndarray:
    """True where another peak ≥ second_peak_ratio × main lies outside the exclusion band."""
    H, W = S.shape
    band = np.maximum(4.0, 2.0 * np.where(np.isfinite(width), width, 0.0)) if p.exclusion_px is None \
        else np.full(W, float(p.exclusion_px))
    band = np.minimum(np.ceil(band).astype(int), H)
    # Blank each column's band around its main peak in a copy; what is left is the runner-up.
    offsets = np.arange(-int(band.max()), int(band.max()) + 1)[:, None]
    rows = r[None, :] + offsets
    inside = (np.abs(offsets) <= band[None, :]) & (rows >= 0) & (rows < H)
    cols = np.broadcast_to(np.arange(W)[None, :], rows.shape)
    masked = S.copy()
    masked[rows[inside], cols[inside]] = -np.inf
    second = masked.max(axis=0)
    far = (second >= p.second_peak_ratio * peak) & (second >= p.min_peak)
    return far | _near_peak(S, r, peak, band, p)


def _near_peak(S, r, peak, band, p: DetectParams) -> np.ndarray:
    """True where, inside the exclusion band, the profile falls from the main peak to below
    half of a later sample and rises to that sample, at least ``second_peak_ratio`` × main and
    ``min_peak``: a second line (a reflection) 2-4 px away, which the band hid (``cog`` then
    averaged the two lines, ``gauss`` took either; the band's floor of 4 rows is three times
    the default line's width). One line's flank only falls."""
    H, W = S.shape
    cols = np.arange(W)
    out = np.zeros(W, dtype=bool)
    for sign in (-1, 1):
        low = np.asarray(peak, dtype=np.float64).copy()  # the lowest sample so far going out
        for k in range(1, int(band.max()) + 1):
            rows = r + sign * k
            inside = (rows >= 0) & (rows < H) & (k <= band)
            v = np.where(inside, S[np.clip(rows, 0, H - 1), cols], -np.inf)
            out |= inside & (v >= p.second_peak_ratio * peak) & (v >= p.min_peak) & (low < 0.5 * v)
            low = np.where(inside, np.minimum(low, v), low)
    return out


def _log_samples(C, r, cols) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Logarithms of each column's samples at rows r − 1, r, r + 1 (r inside the image)."""
    tiny = 1e-12
    with np.errstate(divide="ignore", invalid="ignore"):
        return tuple(np.log(np.maximum(C[r + k, cols].astype(np.float64), tiny)) for k in (-1, 0, 1))


def _log_parabola(C, r, cols) -> np.ndarray:
    """Sub-pixel offset of a Gaussian through the peak sample and its neighbours."""
    lm, l0, lp = _log_samples(C, r, cols)
    den = lm - 2.0 * l0 + lp
    with np.errstate(divide="ignore", invalid="ignore"):
        d = 0.5 * (lm - lp) / den
    return np.where((den < 0) & (np.abs(d) <= 1.0), d, np.nan)


def _centre_of_gravity(C, r, peak, p: DetectParams) -> np.ndarray:
    """Sub-pixel offset of the centre of gravity from the peak row r."""
    half = p.window_px
    win = _window(C, r, half).astype(np.float64)
    H = C.shape[0]
    offsets = np.arange(-half, half + 1)[:, None]
    rows = r[None, :] + offsets
    w = np.maximum(win - p.cog_level * peak[None, :], 0.0)
    w[(rows < 0) | (rows > H - 1)] = 0.0
    total = w.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return (w * offsets).sum(axis=0) / total  # from the peak row


CENTRE_FLOOR_PX = 0.002  # the centre's uncertainty on a whole, noise-free line (point-sampled Gaussian)
LOCAL_WIDTH_COLUMNS = 9  # the reference width for a column's uncertainty: the median over this many
THRESHOLD_SIGMA_PX = 0.5 / np.sqrt(3.0)  # the mean of two ends each uniform over ±0.5 px


def _profile_sigma(S: np.ndarray, r: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """σ₃ (W,) px: the width of a Gaussian through the peak sample and its two neighbours
    (NaN where the three do not make a peak)."""
    lm, l0, lp = _log_samples(S, _clamp(r, 1, S.shape[0] - 2), cols)
    den = (lm - l0) + (lp - l0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den < 0, np.sqrt(-1.0 / den), np.nan)


def _image_noise(C: np.ndarray, r: np.ndarray, p: DetectParams) -> float:
    """Standard deviation of the contrast where there is no line (robust: from the median
    absolute deviation of the pixels below half the detection threshold, more than
    ``window_px`` rows from their column's peak ``r``: the line's own flanks are not noise,
    and how many of them an image holds depends on how many rows around the line it has)."""
    far = np.abs(np.arange(C.shape[0])[:, None] - r[None, :]) > p.window_px
    dark = C[far & (C < 0.5 * p.min_peak)]
    if dark.size < 16:
        return 0.0
    dark = dark[:: max(1, dark.size // 20000)]
    return 1.4826 * _median(np.abs(dark - _median(dark)))


def _local_median(values: np.ndarray, ok: np.ndarray, n: int) -> np.ndarray:
    """Running median of ``values`` over ``n`` neighbouring ``ok`` entries (NaN elsewhere)."""
    out = np.full(len(values), np.nan)
    idx = np.flatnonzero(ok)
    if len(idx) == 0:
        return out
    v = values[idx]
    half = n // 2
    padded = np.concatenate([np.full(half, v[0]), v, np.full(half, v[-1])])
    # The middle of an odd window by partition: np.median's own, without its checks (a third
    # of a frame's detection went to them).
    windows = np.lib.stride_tricks.as_strided(padded, (len(v), 2 * half + 1), (padded.strides[0],) * 2)
    out[idx] = np.partition(windows, half, axis=1)[:, half]
    return out


CUT_BOUND_MIN_SIGMA_PX = 0.5  # below this line σ a sliver of light cut at a flank sample moves the fit without bound


def _cut_shift_bound(light: np.ndarray, line_sigma_px: float, shape: np.ndarray) -> np.ndarray:
    """(W,) px: the most a cut across the line can have moved each column's three-point
    centre, from the share ε of light the column lacks against its neighbours: ``light``
    (W,) is each column's light around its peak (:func:`_lit_window`), the reference its
    median over LOCAL_WIDTH_COLUMNS.

    Three samples cannot tell a line cut on one side from one that is wider on both: each
    changes σ₃ and the fit alike, and the flank term states the shift a cut would make.
    Light tells them apart. A strip the surface's slope spreads keeps its light; a strip an
    edge cuts loses the share it hides. For a Gaussian line cut on one side at any depth
    and sub-pixel phase, point-sampled or pixel-integrated, the three-point centre moves by
    at most about max(2.6, 1.7/σ²)·ε px for a line σ (as fitted) ≥ CUT_BOUND_MIN_SIGMA_PX,
    found by sweeping the cut and the phase: the worst cases are 4.5ε at 0.55 px
    point-sampled, 3.5ε at 0.58 px pixel-integrated and 2.4ε at 2.5 px; a point-sampled line
    of 0.5 px reaches 7.3ε against the bound's 6.8ε. A column with as much light as its
    neighbours has no cut to state; narrower lines, and columns whose light cannot be
    compared, keep the flank term whole (inf)."""
    if not (np.isfinite(line_sigma_px) and line_sigma_px >= CUT_BOUND_MIN_SIGMA_PX):
        return np.full(len(light), np.inf)
    ok = np.isfinite(shape) & (light > 0)
    reference = _local_median(light, ok, LOCAL_WIDTH_COLUMNS)
    with np.errstate(divide="ignore", invalid="ignore"):
        lacking = np.clip(1.0 - light / reference, 0.0, 1.0)
    per_light = max(2.6, 1.7 / line_sigma_px ** 2)
    return np.where(ok & np.isfinite(lacking), per_light * lacking, np.inf)


SKEW_WINDOW_SIGMAS = 3.0  # the profile's moments are taken over ± this many line σ around the peak


def _lit_window(S: np.ndarray, r: np.ndarray, line_sigma_px: float) -> tuple[np.ndarray, np.ndarray]:
    """(row offsets (2h+1, 1), light (2h+1, W)): each column's contrast within
    ±SKEW_WINDOW_SIGMAS line σ (at least ±2 rows) of its peak row ``r``, negatives as 0: what
    the profile's moments (:func:`_skew_shift`) and its light (:func:`_cut_shift_bound`) are
    read from."""
    half = max(2, int(np.ceil(SKEW_WINDOW_SIGMAS * line_sigma_px)))
    offsets = np.arange(-half, half + 1, dtype=np.float64)[:, None]
    return offsets, np.maximum(_window(S, r, half), 0.0)


def _skew_shift(offsets: np.ndarray, w: np.ndarray, r: np.ndarray, rows_px: int) -> np.ndarray:
    """(W,) px: how far the lit strip's curvature across the line moves each column's centre,
    read off the profile's asymmetry. The camera maps the strip's width x to rows as
    a·x + c·x² once the surface bends across the line (c from its curvature). For the
    strip's Gaussian of σ in x the image is skewed: its mean moves by c·σ², and its peak,
    which the three-point fit finds (the density φ(x)/|a + 2cx| is largest at
    x ≈ −2cσ²/a), by 2cσ² the other way. To first order in c, μ₃ = 6a²cσ⁴ and
    var = a²σ², so the peak's shift is μ₃ / (3·var). Moments of the window ``w`` around the
    peak row (:func:`_lit_window`) of an image ``rows_px`` high; a symmetric profile gives 0.
    Sampling reads as skew on a narrow line: a whole Gaussian of σ 0.65 px reads under
    0.01 px at any sub-pixel phase, of σ 0.55 px up to 0.04 px, of σ 0.45 px up to 0.13 px
    (docs/optics.md says what taking that out did)."""
    half = (len(offsets) - 1) // 2
    # Within `half` rows of the image's first or last row the sensor cuts a tail off, which
    # would read as asymmetry (and a shrunken window misreads a whole Gaussian by up to 0.1 px):
    # there the asymmetry is not measured (0).
    whole = (r >= half) & (r <= rows_px - 1 - half)
    with np.errstate(divide="ignore", invalid="ignore"):
        total = w.sum(axis=0)
        mean = (w * offsets).sum(axis=0) / total
        d = offsets - mean
        var = (w * d * d).sum(axis=0) / total
        return np.where(whole, np.abs((w * d ** 3).sum(axis=0) / total) / (3.0 * var), 0.0)


def _centre_sigma(C, S, r, cols, shape, shape_median, p: DetectParams) -> np.ndarray:
    """Uncertainty (W,) px of each column's centre: the disagreement of the profile's two
    flanks if the line is as wide as its neighbours' (half of |σ_ref²/σ₃² − 1|, σ_ref the
    median over LOCAL_WIDTH_COLUMNS columns: the whole line's width changes along the line
    with the surface's slope, a cut one from one column to the next) as far as the light the
    column lacks allows (:func:`_cut_shift_bound`), the shift its asymmetry shows
    (:func:`_skew_shift`: the strip bent across the line), the image noise through the
    three-point fit, and a floor, added in quadrature."""
    H = S.shape[0]
    rr = _clamp(r, 1, H - 2)
    reference = _local_median(shape, np.isfinite(shape), LOCAL_WIDTH_COLUMNS)
    line_sigma = shape_median if np.isfinite(shape_median) else 1.0
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        flanks = 0.5 * np.abs(reference ** 2 / shape ** 2 - 1.0)
        noise = _image_noise(C, r, p)
        fit = 0.5 * line_sigma ** 2 * noise * np.hypot(1.0 / S[rr - 1, cols], 1.0 / S[rr + 1, cols])
    # each at most 0.5 px, NaN (no measure) counting as 0.5: fmin keeps the number where one is NaN
    offsets, lit = _lit_window(S, r, line_sigma)
    flanks = np.fmin(np.fmin(flanks, _cut_shift_bound(lit.sum(axis=0), line_sigma, shape)), 0.5)
    fit = np.fmin(fit, 0.5)
    skew = np.fmin(_skew_shift(offsets, lit, r, H), 0.5)
    return np.minimum(np.sqrt(CENTRE_FLOOR_PX ** 2 + flanks ** 2 + skew ** 2 + fit ** 2), 0.5)


def _wider_than_the_line(width: np.ndarray, code: np.ndarray, p: DetectParams) -> np.ndarray:
    ok = (code == 0) & np.isfinite(width)
    if p.max_width_ratio is None or ok.sum() < 8:
        return np.zeros(len(width), bool)
    return width > p.max_width_ratio * _median(width[ok])


def _smoothing(C: np.ndarray, p: DetectParams) -> float:
    """σ of the matched smoothing: from the parameters, or from the median line width.

    A line narrower than NARROW_LINE_SIGMA_PX is read unsmoothed: smoothing it biases
    the three-point fit towards pixel centres by more than it takes off the noise
    (synthetic lines at 2 % noise, σ 0.6 px: 0.024 px smoothed, 0.022 px not; a
    rendered sphere through a noisy sensor: 33 µm RMS smoothed, 13 µm not), while a
    wider one gains from it (σ 1.5 px: 0.029 against 0.058 px). A flat-topped line
    (``flat_top``) is always smoothed."""
    if p.smoothing_px is not None:
        return float(p.smoothing_px)
    # Every 8th column is plenty for a median width.
    C = np.ascontiguousarray(C[:, ::8]) if C.shape[1] >= 64 else C
    r = _argmax_rows(C)
    peak = C[r, np.arange(C.shape[1])]
    lit = peak >= p.min_peak
    if not lit.any():
        return 0.8
    w = _fwhm(C[:, lit], r[lit], peak[lit], _width_reach(p, C.shape[0]))
    w = w[np.isfinite(w)]
    if not w.size:
        return 0.8
    sigma_line = _median(w) / 2.355
    if p.flat_top:
        return max(0.8, sigma_line)
    return sigma_line if sigma_line >= NARROW_LINE_SIGMA_PX else 0.0


def _smooth_columns(C: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian smoothing along each column only (no mixing of neighbouring columns)."""
    half = int(np.ceil(4 * sigma))
    k = cv2.getGaussianKernel(2 * half + 1, sigma, cv2.CV_32F)
    return cv2.sepFilter2D(C, -1, np.ones((1, 1), np.float32), k, borderType=cv2.BORDER_REPLICATE)


def _steger(C, S, r, sig: float) -> np.ndarray:
    """Ridge centre per column, as an offset from the peak row r: Hessian ridge test at the
    peak, then Newton on the smoothed profile."""
    H, W = C.shape
    cols = np.arange(W)
    cl, cr = _clamp(cols - 1, 0, W - 1), _clamp(cols + 1, 0, W - 1)
    s = lambda dr, cc: S[r + dr, cc].astype(np.float64)  # noqa: E731
    syy = s(1, cols) - 2 * s(0, cols) + s(-1, cols)
    sxx = s(0, cr) - 2 * s(0, cols) + s(0, cl)
    sxy = 0.25 * (s(1, cr) - s(1, cl) - s(-1, cr) + s(-1, cl))
    # Eigen-decomposition of [[sxx, sxy], [sxy, syy]]: a ridge has one strongly
    # negative eigenvalue whose eigenvector (the line normal) is mostly along the rows.
    tr_half = 0.5 * (sxx + syy)
    disc = np.sqrt(0.25 * (sxx - syy) ** 2 + sxy ** 2)
    lam_across = tr_half - disc
    lam_along = tr_half + disc
    ridge = (lam_across < 0) & (np.abs(lam_across) > np.abs(lam_along))

    # Newton on d/dv of the Gaussian-smoothed profile, evaluated exactly at sub-pixel v:
    # S(v) = Σ_k C[k]·g(v − k), with g the smoothing Gaussian.
    half = int(np.ceil(4 * sig)) + 2
    win = _window(C, r, half).astype(np.float64)
    k = np.arange(-half, half + 1, dtype=np.float64)[:, None]  # rows relative to the peak row
    v = np.zeros(W)
    for _ in range(6):
        x = (v[None, :] - k) / sig
        g = np.exp(-0.5 * x * x)
        d1 = np.sum(win * (-x / sig) * g, axis=0)
        d2 = np.sum(win * ((x * x - 1.0) / sig ** 2) * g, axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(d2 < 0, -d1 / d2, 0.0)
        v = v + _clamp(step, -0.5, 0.5)
    ok = ridge & (np.abs(v) <= 1.0)
    return np.where(ok, v, np.nan)  # from the peak row


def _detect_threshold(C, rgb, p: DetectParams, code: np.ndarray, row_offset: int = 0) -> LineDetection:
    """The paper's method: HSV saturation threshold, centre of the lit run in each column."""
    H, W = C.shape
    cols = np.arange(W)
    if rgb is None:
        lit = (C >= p.min_peak).astype(np.uint8)  # grey image: threshold the intensity
    else:
        hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)  # float: H in degrees, S and V in 0..1
        lit = cv2.inRange(hsv, (0.0, p.hsv_saturation, p.hsv_value), (360.0, 1.0, np.inf)) // 255
    count = cv2.reduce(lit, 0, cv2.REDUCE_SUM, dtype=cv2.CV_32S).ravel()
    first = cv2.reduceArgMax(lit, 0).ravel()
    last = H - 1 - cv2.reduceArgMax(np.ascontiguousarray(lit[::-1]), 0).ravel()
    peak = C.max(axis=0)
    code[(code == 0) & (count == 0)] = LineCode.NO_LINE
    # A column whose lit pixels do not form one run holds two separated lines.
    code[(code == 0) & (count != last - first + 1)] = LineCode.AMBIGUOUS
    # A run that touches the first or last row may go on beyond it: its centre is unknown (the
    # other methods' peak on the edge row; this one reported such runs as good).
    code[(code == 0) & ((first == 0) | (last == H - 1))] = LineCode.EDGE
    width = np.where(count > 0, count.astype(np.float64), np.nan)
    code[(code == 0) & (width > p.max_width_px)] = LineCode.TOO_WIDE
    r = _argmax_rows(C)
    code[(code == 0) & _saturated(C if rgb is None else rgb, r, p)] = LineCode.SATURATED
    row = np.where(code == 0, 0.5 * ((first + row_offset) + (last + row_offset)), np.nan)
    # The centre of a run of whole pixels: its ends are each uncertain by up to half a pixel.
    sigma_px = np.where(code == 0, THRESHOLD_SIGMA_PX, np.nan)
    return LineDetection(cols, row, peak.astype(np.float64), width, code, "threshold", (H, W), r + row_offset,
                         sigma_px)
