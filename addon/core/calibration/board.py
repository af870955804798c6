"""The calibration target: a ChArUco board (a chessboard with ArUco markers in its white
squares) printed on a plate.

Board frame (OpenCV's): the origin at the pattern's top-left corner, x along the rows of
squares, y down the printed image, z into the plate. The printed image's texel (row r,
column c) covers x ∈ [c, c + 1] / ppm, y ∈ [r, r + 1] / ppm (mm), so the texture's square
edges lie exactly where the board model puts them. The plate extends ``margin_mm`` beyond
the pattern on every side (white).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import InputError

DICTIONARIES = ("DICT_4X4_50", "DICT_4X4_100", "DICT_5X5_50", "DICT_5X5_100", "DICT_6X6_50", "DICT_APRILTAG_36h11")
MIN_CORNERS = 6  # corners a view needs before it counts (a pose from fewer is fragile)


@dataclass(frozen=True)
class ChArUcoBoard:
    """squares : (columns along x, rows along y); square_mm, marker_mm : their sides;
    dictionary : the ArUco dictionary's OpenCV name; margin_mm : white plate around the pattern;
    thickness_mm : the plate's thickness (it lies on the table)."""

    squares: tuple = (7, 5)
    square_mm: float = 10.0
    marker_mm: float = 7.5
    dictionary: str = "DICT_4X4_50"
    margin_mm: float = 5.0
    thickness_mm: float = 3.0

    def __post_init__(self) -> None:
        sq = tuple(self.squares)
        if len(sq) != 2 or not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) and 3 <= v <= 40
                                   for v in sq):
            raise InputError(f"board squares must be two whole numbers in [3, 40] (columns, rows), got {list(sq)}")
        object.__setattr__(self, "squares", (int(sq[0]), int(sq[1])))
        for key in ("square_mm", "marker_mm", "margin_mm", "thickness_mm"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise InputError(f"board {key} must be a finite number ≥ 0, got {v!r}")
        if not 0 < self.marker_mm < self.square_mm:
            raise InputError(f"board marker_mm ({self.marker_mm:g}) must be > 0 and smaller than square_mm "
                             f"({self.square_mm:g})")
        if self.dictionary not in DICTIONARIES:
            raise InputError(f"board dictionary {self.dictionary!r} is not one of: {', '.join(DICTIONARIES)}")
        markers = (sq[0] * sq[1]) // 2
        size = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary)).bytesList.shape[0]
        if markers > size:
            raise InputError(f"a {sq[0]}x{sq[1]} board needs {markers} markers; {self.dictionary} has {size}")

    @property
    def pattern_mm(self) -> tuple[float, float]:
        """(width along x, height along y) of the printed pattern, mm."""
        return self.squares[0] * self.square_mm, self.squares[1] * self.square_mm

    @property
    def plate_mm(self) -> tuple[float, float]:
        w, h = self.pattern_mm
        return w + 2 * self.margin_mm, h + 2 * self.margin_mm

    def cv_board(self) -> "cv2.aruco.CharucoBoard":
        return _cv_board(self.squares, float(self.square_mm), float(self.marker_mm), self.dictionary)

    @property
    def corners_mm(self) -> np.ndarray:
        """(n, 3) the inner chessboard corners in the board frame (z = 0), indexed by corner id."""
        return np.asarray(self.cv_board().getChessboardCorners(), dtype=np.float64).reshape(-1, 3)

    def texture(self, px_per_mm: int = 20) -> np.ndarray:
        """(H, W) uint8, the printed pattern (no margin), ``px_per_mm`` texels per mm; each
        square a whole number of texels so that the edges fall on texel edges."""
        per_square = self.square_mm * px_per_mm
        if abs(per_square - round(per_square)) > 1e-9:
            raise InputError(f"{px_per_mm} texels per mm do not make whole squares of {self.square_mm:g} mm")
        w, h = (int(round(n * per_square)) for n in self.squares)
        return self.cv_board().generateImage((w, h), marginSize=0, borderBits=1)

    def detect(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """ChArUco corners in one image: ids (k,) int and positions (k, 2) float, OpenCV pixels.

        ``image`` : (H, W) or (H, W, 3) float (linear, 1 = white) or uint8. Empty arrays where
        the board is not found."""
        img = np.asarray(image)
        if img.ndim == 3:
            img = img[..., :3].mean(axis=2)
        if img.dtype != np.uint8:
            finite = np.nan_to_num(img.astype(np.float64), nan=0.0, posinf=0.0, neginf=0.0)
            top = np.percentile(finite, 99.5)
            img = np.clip(finite / max(top, 1e-12) * 255.0, 0, 255).astype(np.uint8)
        params = cv2.aruco.CharucoParameters()
        detector_params = cv2.aruco.DetectorParameters()
        detector_params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
        detector = cv2.aruco.CharucoDetector(self.cv_board(), params, detector_params)
        corners, ids, _, _ = detector.detectBoard(img)
        if ids is None or len(ids) == 0:
            return np.zeros(0, int), np.zeros((0, 2))
        ids = ids.ravel().astype(int)
        corners = corners.reshape(-1, 2).astype(np.float32)
        if len(ids) >= 2:
            # Refine each corner inside the clear square around it: the detector's own window
            # reaches the markers' edges on a small sensor and pulls the corner by tenths of a pixel.
            mm = self.corners_mm[ids[:12], :2]
            px = corners[:12].astype(np.float64)
            i, j = np.triu_indices(len(mm), 1)
            px_per_mm = float(np.median(np.linalg.norm(px[i] - px[j], axis=1) / np.linalg.norm(mm[i] - mm[j], axis=1)))
            half = int(np.clip(0.8 * 0.5 * (self.square_mm - self.marker_mm) * px_per_mm, 2, 10))
            crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-4)
            gray = img.astype(np.float32)
            corners = cv2.cornerSubPix(gray, corners.reshape(-1, 1, 2), (half, half), (-1, -1), crit).reshape(-1, 2)
        return ids, corners.astype(np.float64)


@functools.lru_cache(maxsize=16)
def _cv_board(squares, square_mm, marker_mm, dictionary):
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
    return cv2.aruco.CharucoBoard(squares, square_mm, marker_mm, d)


def board_for(probe) -> ChArUcoBoard:
    """A board that fills about 80 % of the probe cameras' view at mid-range, in 7 × 5
    squares of a whole number of half millimetres (a printed board of sensible size)."""
    z0, z1 = probe.z_range_mm
    depth = 0.5 * (z0 + z1)
    view = 2.0 * probe.line_half_length_mm(depth)  # along the line; across, the tilt shortens it
    square = max(0.5, round(0.8 * view / 7 / 0.5) * 0.5)
    return ChArUcoBoard((7, 5), square, 0.75 * square, margin_mm=0.5 * square)
