"""What the probe believes about itself: the camera and laser model triangulation uses.

A probe renders with its true geometry (:class:`~addon.core.optics.probe.Probe`: two
ideal pinhole cameras mirrored about the laser plane X = 0). A real probe measures
with what its calibration found: each camera's intrinsics (f_x, f_y, c_x, c_y), its
lens distortion, its pose in the probe frame, and the laser plane. A probe carrying a
:class:`ProbeCalibration` triangulates with that instead of the truth, so the cost of
a calibration shows up in the cloud.

The calibration is expressed in the probe frame the probe's own mount (T_L^6) defines:
a hand-eye calibration finds the cameras in the flange frame, and the nominal mount
takes them into the probe frame. A calibrated laser plane need not be X = 0 there.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import InputError
from ..kinematics.transforms import check_transform

NOMINAL_PLANE = (np.array([1.0, 0.0, 0.0]), 0.0)  # X = 0: the laser plane of the probe frame
NOMINAL_PLANE[0].setflags(write=False)
# How far a calibration may take a probe from its design (ProbeCalibration.implausible): it
# corrects by small amounts. Generous: a real one is within tenths of a degree and of a mm.
PLAUSIBLE_TURN_DEG = 10.0  # the laser plane or a camera turned
PLAUSIBLE_SHIFT = 0.2      # ... or moved, times the probe's baseline a_mm
PLAUSIBLE_FOCAL = 1.3      # a focal length, within this factor of the design's
PLAUSIBLE_K1 = 2.0         # the radial distortion's first coefficient


@dataclass(frozen=True, eq=False)
class CameraModel:
    """One calibrated camera.

    K : (3, 3) intrinsic matrix, OpenCV convention (pixel centres at integers)
    distortion : (5,) Brown–Conrady (k1, k2, p1, p2, k3), OpenCV's form; zeros for none
    cam2probe : (4, 4) mm, the camera frame (OpenCV: x right, y down, z forward) in the probe frame
    """

    K: np.ndarray
    distortion: np.ndarray
    cam2probe: np.ndarray

    def __post_init__(self) -> None:
        K = np.array(self.K, dtype=np.float64)
        if K.shape != (3, 3) or not np.isfinite(K).all():
            raise InputError(f"camera K must be a finite 3x3 matrix, got shape {K.shape}")
        if not (K[0, 0] > 0 and K[1, 1] > 0) or K[1, 0] or K[2, 0] or K[2, 1] or K[2, 2] != 1.0:
            raise InputError("camera K must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0")
        dist = np.zeros(5)
        given = np.asarray(self.distortion, dtype=np.float64).ravel()
        if len(given) not in (0, 4, 5) or not np.isfinite(given).all():
            raise InputError(f"camera distortion must be 4 or 5 finite coefficients (k1, k2, p1, p2[, k3]), "
                             f"got {given.tolist()}")
        dist[:len(given)] = given
        T = check_transform(self.cam2probe, "camera pose (cam2probe)")
        for name, value in (("K", K), ("distortion", dist), ("cam2probe", T)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def distorted(self) -> bool:
        return bool(np.any(self.distortion != 0.0))

    def undistort(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Detected pixel positions (n,) -> where this camera's ideal pinhole (same K) sees them."""
        if not self.distorted or len(u) == 0:
            return u, v
        pts = np.stack([u, v], axis=1).reshape(-1, 1, 2).astype(np.float64)
        out = cv2.undistortPoints(pts, self.K, self.distortion, P=self.K).reshape(-1, 2)
        return out[:, 0], out[:, 1]

    def rays(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rays through undistorted pixels (n, 2): origin (3,) and unit directions (n, 3), probe frame."""
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        fx, s, cx = self.K[0]
        fy, cy = self.K[1, 1], self.K[1, 2]
        y = (uv[:, 1] - cy) / fy
        x = (uv[:, 0] - cx - s * y) / fx
        d = np.column_stack([x, y, np.ones(len(uv))]) @ self.cam2probe[:3, :3].T
        return self.cam2probe[:3, 3].copy(), d / np.linalg.norm(d, axis=1, keepdims=True)


@dataclass(frozen=True, eq=False)
class ProbeCalibration:
    """A probe's calibration: two cameras and the laser plane n·x = offset (probe frame, mm).

    cameras : (camera 0, camera 1)
    plane_normal : (3,) the laser plane's normal, pointing towards camera 0's side: a direction,
        made unit length (probe.toml's ``normal`` may be given at any length)
    plane_offset_mm : the plane's signed distance (mm) from the probe origin along that unit
        normal, as given (not scaled with the normal's length)
    source : how it was obtained (for people)
    """

    cameras: tuple
    plane_normal: np.ndarray
    plane_offset_mm: float
    source: str = ""

    def __post_init__(self) -> None:
        if len(self.cameras) != 2 or not all(isinstance(c, CameraModel) for c in self.cameras):
            raise InputError("a probe calibration needs two CameraModel objects (camera 0, camera 1)")
        n = np.asarray(self.plane_normal, dtype=np.float64).ravel()
        norm = float(np.linalg.norm(n)) if n.shape == (3,) and np.isfinite(n).all() else 0.0
        if norm < 1e-9:
            raise InputError(f"laser plane normal must be three finite numbers, not all zero; got {n.tolist()}")
        d = float(self.plane_offset_mm)
        if not np.isfinite(d):
            raise InputError(f"laser plane offset must be a finite number of mm, got {self.plane_offset_mm!r}")
        n = n / norm  # a direction: the offset is a distance in mm along it, whatever the length given
        n.setflags(write=False)
        object.__setattr__(self, "cameras", tuple(self.cameras))
        object.__setattr__(self, "plane_normal", n)
        object.__setattr__(self, "plane_offset_mm", d)

    def implausible(self, probe) -> str | None:
        """Why this cannot be a calibration of ``probe`` (a correction of its design by small
        amounts), or None: a laser plane or a camera turned or moved far from the design, a
        focal length far from it, a principal point off the sensor, a k1 no lens has. (A
        plane 90° off, or a focal length of half a pixel, loaded and scanned 0 points that
        blamed the sensor; k1 = 5 scanned at 4.7 mm RMS without a word.)"""
        n = self.plane_normal
        tilt = float(np.degrees(np.arccos(min(abs(float(n[0])), 1.0))))
        if tilt > PLAUSIBLE_TURN_DEG:
            return f"the laser plane's normal is {tilt:.3g}° from the design's (at most {PLAUSIBLE_TURN_DEG:g}°)"
        mid = 0.5 * sum(probe.z_range_mm)
        shift = abs((self.plane_offset_mm - float(n[2]) * mid) / float(n[0]))
        room = PLAUSIBLE_SHIFT * probe.a_mm
        if shift > room:
            return f"the laser plane lies {shift:.3g} mm from the design's at mid-range (at most {room:.3g} mm)"
        for c, cam in enumerate(self.cameras):
            where = f"camera {c}"
            T0 = probe.cam2probe(c)
            moved = float(np.linalg.norm(cam.cam2probe[:3, 3] - T0[:3, 3]))
            if moved > room:
                return f"{where} lies {moved:.3g} mm from the design's position (at most {room:.3g} mm)"
            R = T0[:3, :3].T @ cam.cam2probe[:3, :3]
            turn = float(np.degrees(np.arccos(np.clip(0.5 * (np.trace(R) - 1.0), -1.0, 1.0))))
            if turn > PLAUSIBLE_TURN_DEG:
                return f"{where} is turned {turn:.3g}° from the design (at most {PLAUSIBLE_TURN_DEG:g}°)"
            for key, i in (("fx_px", 0), ("fy_px", 1)):
                ratio = float(cam.K[i, i] / probe.K[i, i])
                if not 1.0 / PLAUSIBLE_FOCAL <= ratio <= PLAUSIBLE_FOCAL:
                    return (f"{where}'s {key} {cam.K[i, i]:.4g} is {ratio:.3g} times the design's {probe.K[i, i]:.4g} "
                            f"(within a factor {PLAUSIBLE_FOCAL:g})")
            cx, cy = float(cam.K[0, 2]), float(cam.K[1, 2])
            if not (0.0 <= cx <= probe.cols_px and 0.0 <= cy <= probe.rows_px):
                return f"{where}'s principal point ({cx:.4g}, {cy:.4g}) px lies off its {probe.cols_px}x{probe.rows_px} sensor"
            k1 = float(cam.distortion[0]) if len(cam.distortion) else 0.0
            if abs(k1) > PLAUSIBLE_K1:
                return f"{where}'s k1 {k1:.3g} is beyond any lens's (at most {PLAUSIBLE_K1:g} either way)"
        return None

    @classmethod
    def of(cls, probe, source: str = "the probe's true geometry") -> "ProbeCalibration":
        """The exact calibration of a probe's true geometry (a perfect calibration)."""
        cams = tuple(CameraModel(probe.K, np.zeros(5), probe.cam2probe(c)) for c in (0, 1))
        return cls(cams, NOMINAL_PLANE[0], NOMINAL_PLANE[1], source)
