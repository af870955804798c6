"""The laser probe: one line laser and two cameras (paper Section 4.2, Fig. 3, Eq. 6–7).

Probe frame L (the paper's XYZ): the laser sits at the origin, its beam points
along +Z and its fan lies in the YZ plane (the laser plane, X = 0). Two identical
cameras sit mirrored about that plane. Camera 0 is at (a, 0, b) and camera 1 at
(−a, 0, b); each looks at the laser plane with its optical axis at angle φ from
the beam, and sees ±γ about that axis along the triangulation direction.

Sensor: H rows along the triangulation direction, W columns along the laser line,
square pixels, focal length f = H / (2 tan γ) in pixels (so the sensor's outer
row edges see exactly φ ± γ).

Pixel convention (OpenCV): pixel centres at integer coordinates, u = column,
v = row, so the principal point is ((W − 1)/2, (H − 1)/2) and the sensor spans
u ∈ [−0.5, W − 0.5], v ∈ [−0.5, H − 0.5]. The camera frame is OpenCV's (x right,
y down, z forward). For camera 0, x points along +Y of the probe, and the far end
of the range images at the top (small v). The paper's pixel coordinates are
p_x = ±(u − c_x) (+ for camera 0, − for its mirror image, camera 1) and
p_y = c_y − v.

Eq. 7 in the paper (range and line lengths) follows from the edge rays at φ ± γ.
The range (z) is exact; the line lengths carry the same approximation as Eq. 6's
P_Y (f where the exact ray has √(f² + p_y²)), so the exact half-lengths are
shorter by cos γ when W = H. Both are available: :meth:`Probe.line_lengths_mm`
(exact) and :meth:`Probe.paper_line_lengths_mm` (Eq. 7 verbatim).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import InputError
from ..tolerances import TOL
from ..kinematics.transforms import check_transform, make_pose, rigid_inverse
from .calibrated import NOMINAL_PLANE, CameraModel, ProbeCalibration

# A camera ray meeting the laser plane at less than this is grazing: its point is dropped
# (triangulate). A probe whose whole view meets the plane so is refused.
MIN_ANGLE_DEG = 2.0

CAMERAS = (0, 1)
# A sensor side: from Blender's smallest render (4 px: it rendered 160 x 3 as 160 x 4, and the
# sensor model then failed on the mismatch) ...
MIN_PIXELS = 4
MAX_PIXELS = 100_000
# ... to Blender's largest (a longer side is refused where Blender renders: scene.render)
MAX_RENDER_PIXELS = 65_536
MAX_SENSOR_PIXELS = 50_000_000  # rows × columns at most: one float image of it is 200 MB
MAX_OFFSET_MM = 1e5  # the farthest a camera may sit from the laser (a, b), as probe files allow
EDGE_TOL_PX = TOL.sensor_edge_px
HOUSING_MARGIN_MM = 30.0  # the housing reaches this much beyond the two cameras, in all


@dataclass(frozen=True, eq=False)
class Probe:
    """Probe geometry and sensor. Lengths mm, angles rad, sensor sizes in pixels.

    a_mm : distance of each camera from the laser plane (triangulation baseline / 2)
    b_mm : camera offset along the beam (Z)
    phi_rad : angle between the beam and each camera's optical axis
    gamma_rad : half field of view along the triangulation direction
    rows_px, cols_px : sensor H (triangulation direction) and W (along the line)
    line_width_mm : laser line width, 1/e² full width, at the middle of the range
        (the line keeps its angular width, so it is narrower near, wider far)
    fan_rad : full opening angle of the laser fan in the YZ plane
    wavelength_nm : laser wavelength (speckle and colour in later stages)
    mount : (4, 4) pose of the probe frame in the robot flange frame, the paper's T_L^6
    calibration : what the probe's calibration found (cameras, laser plane); None: the probe
        triangulates with its true geometry. Rendering always uses the true geometry.
    """

    name: str
    a_mm: float
    b_mm: float
    phi_rad: float
    gamma_rad: float
    rows_px: int
    cols_px: int
    line_width_mm: float = 0.3
    fan_rad: float = math.radians(60.0)
    wavelength_nm: float = 650.0
    mount: np.ndarray = field(default_factory=lambda: np.eye(4))
    source: str = ""
    calibration: "ProbeCalibration | None" = None

    def __post_init__(self) -> None:
        who = f"probe {self.name!r}"
        for key in ("a_mm", "b_mm", "phi_rad", "gamma_rad", "line_width_mm", "fan_rad", "wavelength_nm"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating)) or not math.isfinite(v):
                raise InputError(f"{who}: {key} must be a finite number, got {v!r}")
            object.__setattr__(self, key, float(v))
        for key in ("rows_px", "cols_px"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not MIN_PIXELS <= v <= MAX_PIXELS:
                raise InputError(f"{who}: {key} must be a whole number of pixels in [{MIN_PIXELS}, {MAX_PIXELS}], "
                                 f"got {v!r}")
            object.__setattr__(self, key, int(v))
        if self.rows_px * self.cols_px > MAX_SENSOR_PIXELS:  # each side allowed, the whole would not fit in memory
            raise InputError(f"{who}: a sensor of {self.cols_px} x {self.rows_px} px is {self.rows_px * self.cols_px:,} "
                             f"pixels, more than the {MAX_SENSOR_PIXELS:,} allowed (rows_px x cols_px): its images "
                             f"would not fit in memory")
        for key in ("a_mm", "b_mm"):  # as a probe file allows: a probe is not metres across
            if abs(getattr(self, key)) > MAX_OFFSET_MM:
                raise InputError(f"{who}: {key} = {getattr(self, key):g} mm is beyond the ±{MAX_OFFSET_MM:g} mm a "
                                 f"probe's cameras may sit from its laser")
        deg = math.degrees
        if self.a_mm <= 0:
            raise InputError(f"{who}: a = {self.a_mm:g} mm: the cameras must sit beside the laser plane, a > 0")
        if not 0 < self.gamma_rad < math.pi / 2:
            raise InputError(f"{who}: γ = {deg(self.gamma_rad):g}°: the half field of view must be in (0°, 90°)")
        if self.phi_rad - self.gamma_rad <= 0:
            raise InputError(
                f"{who}: φ − γ = {deg(self.phi_rad - self.gamma_rad):.4g}° ≤ 0: the far edge of the view never "
                f"meets the laser plane, so the range has no far limit; need φ > γ (φ = {deg(self.phi_rad):g}°, "
                f"γ = {deg(self.gamma_rad):g}°)")
        if self.phi_rad + self.gamma_rad >= math.pi / 2:
            raise InputError(
                f"{who}: φ + γ = {deg(self.phi_rad + self.gamma_rad):.4g}° ≥ 90°: the near edge of the view points "
                f"away from the laser plane; need φ + γ < 90° (φ = {deg(self.phi_rad):g}°, γ = {deg(self.gamma_rad):g}°)")
        if self.line_width_mm <= 0:
            raise InputError(f"{who}: laser line width must be > 0 mm, got {self.line_width_mm:g}")
        if not 0 < self.fan_rad < math.pi:
            raise InputError(f"{who}: laser fan angle must be in (0°, 180°), got {deg(self.fan_rad):g}°")
        if self.wavelength_nm <= 0:
            raise InputError(f"{who}: laser wavelength must be > 0 nm, got {self.wavelength_nm:g}")
        if self.calibration is not None and not isinstance(self.calibration, ProbeCalibration):
            raise InputError(f"{who}: calibration must be a ProbeCalibration or None, got {self.calibration!r}")
        mount = check_transform(self.mount, f"{who} mount (T_L^6)")
        mount.setflags(write=False)
        object.__setattr__(self, "mount", mount)

    # -- derived optics -----------------------------------------------------------
    @property
    def f_px(self) -> float:
        """Focal length in pixels: f = H / (2 tan γ)."""
        return self.rows_px / (2.0 * math.tan(self.gamma_rad))

    @property
    def principal_point(self) -> tuple[float, float]:
        """(c_x, c_y) = ((W − 1)/2, (H − 1)/2): the sensor centre in OpenCV pixel coordinates."""
        return (self.cols_px - 1) / 2.0, (self.rows_px - 1) / 2.0

    @property
    def K(self) -> np.ndarray:
        """(3, 3) intrinsic matrix, OpenCV convention; the same for both cameras."""
        cx, cy = self.principal_point
        f = self.f_px
        return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])

    @property
    def half_fov_line_rad(self) -> float:
        """Half field of view along the laser line (equals γ when W = H)."""
        return math.atan((self.cols_px / 2.0) / self.f_px)

    def cam2probe(self, camera: int) -> np.ndarray:
        """(4, 4) pose of camera 0 or 1 (OpenCV camera frame) in the probe frame (read-only)."""
        _check_camera(camera)
        cache = self.__dict__.setdefault("_cam2probe_cache", {})  # the probe is immutable: computed once
        if camera not in cache:
            pose = self._cam2probe(camera)
            pose.setflags(write=False)
            cache[camera] = pose
        return cache[camera]

    def _cam2probe(self, camera: int) -> np.ndarray:
        s, c = math.sin(self.phi_rad), math.cos(self.phi_rad)
        side = 1.0 if camera == 0 else -1.0
        z = np.array([-side * s, 0.0, c])          # optical axis, towards the laser plane
        y = np.array([-side * c, 0.0, -s])         # image down: towards the near end of the range
        x = np.cross(y, z)                          # +Y for camera 0, −Y for camera 1
        return make_pose(np.column_stack([x, y, z]), [side * self.a_mm, 0.0, self.b_mm])

    def probe2cam(self, camera: int) -> np.ndarray:
        return rigid_inverse(self.cam2probe(camera))

    # -- Eq. 7 --------------------------------------------------------------------
    @property
    def z_range_mm(self) -> tuple[float, float]:
        """(z_min, z_max) of Eq. 7: where the sensor's outer rows meet the laser plane."""
        a, b, p, g = self.a_mm, self.b_mm, self.phi_rad, self.gamma_rad
        return a / math.tan(p + g) + b, a / math.tan(p - g) + b

    def line_half_length_mm(self, z_mm) -> np.ndarray:
        """Exact half-length (mm) of the laser line the sensor sees at distance z (mm) on the laser plane."""
        z = np.asarray(z_mm, dtype=np.float64)
        # A laser-plane point (0, y, z) images at p_x = f·y / depth, where depth is
        # its distance along the optical axis: (z − b) cos φ + a sin φ.
        depth = (z - self.b_mm) * math.cos(self.phi_rad) + self.a_mm * math.sin(self.phi_rad)
        return (self.cols_px / 2.0) / self.f_px * depth

    def line_lengths_mm(self) -> tuple[float, float]:
        """Exact (L_min, L_max): full line length seen at z_min and z_max."""
        z0, z1 = self.z_range_mm
        return float(2 * self.line_half_length_mm(z0)), float(2 * self.line_half_length_mm(z1))

    def paper_line_lengths_mm(self) -> tuple[float, float]:
        """(L_min, L_max) = (2 y_min, 2 y_max) from Eq. 7 verbatim (tan of the half field of view along the line)."""
        a, p, g = self.a_mm, self.phi_rad, self.gamma_rad
        t = math.tan(self.half_fov_line_rad)
        return 2 * a * t / math.sin(p + g), 2 * a * t / math.sin(p - g)

    # -- projection -----------------------------------------------------------------
    def project(self, points_probe, camera: int = 0) -> np.ndarray:
        """Pixel coordinates (n, 2) = (u, v) of probe-frame points (n, 3) in mm.

        NaN where the point is behind the camera or outside the sensor
        (u ∉ [−0.5, W − 0.5] or v ∉ [−0.5, H − 0.5]). Occlusion is not considered.
        """
        P = np.asarray(points_probe, dtype=np.float64)
        single = P.ndim == 1
        P = np.atleast_2d(P)
        if P.shape[-1] != 3:
            raise InputError(f"points must have shape (n, 3) in mm, got {np.shape(points_probe)}")
        T = self.probe2cam(camera)
        Pc = P @ T[:3, :3].T + T[:3, 3]
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = (Pc[:, :2] / Pc[:, 2:3]) * self.f_px + np.array(self.principal_point)
        e = EDGE_TOL_PX  # points exactly on the sensor edge (the range limits) count as inside
        inside = ((Pc[:, 2] > 0) & (uv[:, 0] >= -0.5 - e) & (uv[:, 0] <= self.cols_px - 0.5 + e)
                  & (uv[:, 1] >= -0.5 - e) & (uv[:, 1] <= self.rows_px - 0.5 + e))
        uv[~inside] = np.nan
        return uv[0] if single else uv

    def pixel_rays(self, uv, camera: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Rays through pixel coordinates (n, 2): origin (3,) and unit directions (n, 3), probe frame."""
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        cx, cy = self.principal_point
        d_cam = np.column_stack([(uv[:, 0] - cx) / self.f_px, (uv[:, 1] - cy) / self.f_px, np.ones(len(uv))])
        T = self.cam2probe(camera)
        d = d_cam @ T[:3, :3].T
        return T[:3, 3].copy(), d / np.linalg.norm(d, axis=1, keepdims=True)

    def body_boxes(self) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """The probe's body as boxes in the probe frame: (name, extents (3,) mm, centre (3,) mm).

        The housing behind the cameras and the laser (what the Blender cell draws), and the
        three heads that reach forward to z = +2 mm: both cameras and the laser."""
        width = 2.0 * self.a_mm + HOUSING_MARGIN_MM
        heads = [("camera 0 head", [self.a_mm, 0.0, self.b_mm - 8.0]),
                 ("camera 1 head", [-self.a_mm, 0.0, self.b_mm - 8.0]),
                 ("laser head", [0.0, 0.0, -8.0])]
        return ([("housing", np.array([width, 40.0, 50.0]), np.array([0.0, 0.0, -33.0]))]
                + [(name, np.array([24.0, 24.0, 20.0]), np.array(c, dtype=np.float64)) for name, c in heads])

    def with_resolution(self, rows_px: int, cols_px: int) -> "Probe":
        """The same optics (a, b, φ, γ) on another sensor."""
        if self.calibration is not None and (rows_px, cols_px) != (self.rows_px, self.cols_px):
            raise InputError(f"probe {self.name!r} carries a calibration made on its {self.cols_px}x{self.rows_px} "
                             f"sensor; it cannot measure at {cols_px}x{rows_px} (calibrate at that resolution)")
        if (rows_px, cols_px) == (self.rows_px, self.cols_px):
            return self
        # The name says the sensor where the rig's does ("..., 160x160)"), so it says the new one.
        size = f"{self.cols_px}x{self.rows_px}"
        name = (self.name.replace(size, f"{cols_px}x{rows_px}") if size in self.name
                else f"{self.name} at {cols_px}x{rows_px} px")
        return replace(self, rows_px=rows_px, cols_px=cols_px, name=name)

    def geometry_differences(self, other: "Probe") -> list[str]:
        """Where ``other``'s geometry (a, b, φ, γ and the mount) differs from this probe's, in
        words: "a_mm 75 there, 60 here" (there: this probe, here: ``other``); empty where they
        are the same to 1e-6 (relative; a float32 field of Blender's panel holds them so)."""
        out = []
        for key, unit, scale in (("a_mm", " mm", 1.0), ("b_mm", " mm", 1.0), ("phi_rad", "°", 180 / math.pi),
                                 ("gamma_rad", "°", 180 / math.pi)):
            there, here = getattr(self, key) * scale, getattr(other, key) * scale
            if abs(there - here) > 1e-6 * max(1.0, abs(here)):
                name = key.replace("_rad", "_deg")
                out.append(f"{name} {there:.6g}{unit} there, {here:.6g}{unit} here")
        if not np.allclose(self.mount, other.mount, rtol=0.0, atol=1e-6):
            out.append("its mount (T_L^6) differs")
        return out

    def with_optics(self, a_mm: float, b_mm: float, phi_rad: float, gamma_rad: float) -> "Probe":
        """The same probe with another geometry (a, b, φ, γ). A calibrated probe refuses one that
        differs: its calibration holds for the geometry it was made on."""
        other = replace(self, a_mm=a_mm, b_mm=b_mm, phi_rad=phi_rad, gamma_rad=gamma_rad)
        if self.calibration is not None:
            differ = self.geometry_differences(other)
            if differ:
                raise InputError(f"probe {self.name!r} carries a calibration made on its own optics "
                                 f"({'; '.join(differ).replace('there', 'calibrated').replace('here', 'asked')}): it "
                                 f"cannot measure with others (choose the probe again to restore them, or calibrate "
                                 f"this geometry)")
        return other

    def measuring_camera(self, camera: int) -> CameraModel:
        """The camera model triangulation uses: the calibration's, else the true one."""
        _check_camera(camera)
        if self.calibration is not None:
            return self.calibration.cameras[camera]
        return CameraModel(self.K, np.zeros(5), self.cam2probe(camera))

    @property
    def measuring_plane(self) -> tuple[np.ndarray, float]:
        """(unit normal (3,), offset mm) of the laser plane triangulation uses (X = 0 uncalibrated)."""
        if self.calibration is not None:
            return self.calibration.plane_normal, self.calibration.plane_offset_mm
        return NOMINAL_PLANE


def _check_camera(camera) -> None:
    if camera not in CAMERAS:
        raise InputError(f"camera must be 0 or 1, got {camera!r}")


def angles_from_range(a_mm: float, b_mm: float, z_min_mm: float, z_max_mm: float) -> tuple[float, float]:
    """(φ, γ) in rad that give the range [z_min, z_max] by Eq. 7, for baseline a and offset b."""
    if not (z_max_mm > z_min_mm > b_mm):
        raise InputError(f"range must satisfy z_max > z_min > b; got z_min = {z_min_mm:g}, "
                         f"z_max = {z_max_mm:g}, b = {b_mm:g} mm")
    near = math.atan(a_mm / (z_min_mm - b_mm))  # φ + γ
    far = math.atan(a_mm / (z_max_mm - b_mm))   # φ − γ
    return 0.5 * (near + far), 0.5 * (near - far)


def check_not_grazing(probe: "Probe") -> None:
    """Refuse a probe whose every camera ray meets the laser plane at less than MIN_ANGLE_DEG:
    a scan would drop every point as grazing and blame its path. (Checked where a probe rig
    is read, not in Probe itself: the triangulation's limit can be lowered through the API.)"""
    total = math.degrees(probe.phi_rad + probe.gamma_rad)
    if total < MIN_ANGLE_DEG:
        raise InputError(
            f"probe {probe.name!r}: φ + γ = {total:.3g}°: every camera ray meets the laser plane at less than "
            f"{MIN_ANGLE_DEG:g}°, so every point would be dropped as grazing; need φ + γ ≥ {MIN_ANGLE_DEG:g}° (a wider "
            f"baseline a_mm for this range, or a wider view)")
