"""A probe calibration from board views, as a robot cell calibrates an eye-in-hand line scanner.

Inputs per view: the robot's flange pose (the controller knows it), the ChArUco corners
each camera found with the cell's lights on and the laser off, and the laser line each
camera detected on the plain plate at the same pose (lights off, laser on).

1. **Intrinsics** per camera (Zhang's method, ``cv2.calibrateCameraExtended``): focal
   lengths, principal point and, when asked, lens distortion (k1, k2, p1, p2).
2. **Hand-eye** (the board lies still on the table, the probe moves): each camera's pose
   in the flange frame X_c and the board's pose in the base frame Z satisfy
   F_i · X_c · C_ci = Z for every view i (F_i flange → base, C_ci board → camera c).
   Park and Martin's closed form (rotation from the logarithms of the relative motions,
   translation by least squares) starts a bundle adjustment (Levenberg–Marquardt) of X_0,
   X_1, Z and both cameras' intrinsics together on the corners' reprojection error: the
   exact flange poses tie every view to one rigid probe, which pins the focal lengths far
   better than Zhang's per-view poses. Its covariance, s²(JᵀJ)⁻¹, gives each parameter's
   standard deviation.
3. **Laser plane**: each line pixel's viewing ray meets the plate (the board plane at that
   view, from the refined poses); the points of all views, in the probe frame, are fitted
   with a plane by SVD. The views' different depths and tilts make the fit determined.

The cameras and the plane are expressed in the probe frame of the probe's nominal mount
(T_L^6), which is what the scan pipeline moves points with.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from ..errors import CalibrationError
from ..kinematics.transforms import make_pose, orthonormalize, rigid_inverse, rotation_angle
from ..optics.calibrated import CameraModel, ProbeCalibration
from ..optics.probe import Probe
from .board import MIN_CORNERS, ChArUcoBoard

MIN_VIEWS = 4          # board views per camera below which Zhang's method is not trusted
MIN_MARKER_PX = 8.0  # ArUco's 4 x 4 bits and border: about a pixel and a third a cell at least
MIN_SPREAD_DEG = 5.0   # the board normals must spread at least this much across the views
MIN_LINE_POINTS = 20   # laser pixels a view needs to add to the plane fit
PLATE_EDGE_MM = 5.0    # laser points this near the plate's edge are left out (the table is near)


@dataclass
class BoardView:
    """One calibration pose.

    flange2base : (4, 4) mm, the robot flange's pose (from the joints)
    ids, corners : per camera, the ChArUco corner ids (k,) and pixels (k, 2) found
    line : per camera, the laser line's pixels (m, 2) on the plain plate (None: no image)
    """

    flange2base: np.ndarray
    ids: list
    corners: list
    line: list = field(default_factory=lambda: [None, None])


@dataclass
class CameraFit:
    """What the calibration found for one camera, with OpenCV's figures of merit."""

    K: np.ndarray
    distortion: np.ndarray
    cam2flange: np.ndarray
    reprojection_error_px: float        # RMS over all corners, final (joint hand-eye and intrinsics)
    zhang_error_px: float               # RMS of the first, per-view intrinsic fit (each view its own pose)
    std_intrinsics: dict                # 1-σ of fx, fy, cx, cy (px) [and k1], from the final fit
    std_pose: dict                      # 1-σ of the camera's position (mm) and rotation (deg) in the flange frame
    views: int
    corners: int


@dataclass
class ProbeFit:
    probe: Probe                        # the nominal probe carrying the calibration
    cameras: list
    board2base: np.ndarray
    plane_rms_mm: float                 # RMS distance of the laser points from the fitted plane
    plane_points: int
    plane_views: int
    plane_std: dict                     # 1-σ of the plane's tilt (deg) and offset at mid-range (mm): _plane_std


def calibrate_probe(probe: Probe, board: ChArUcoBoard, views: list[BoardView], *, distortion: bool = False,
                    source: str = "") -> ProbeFit:
    """The calibrated probe from board views (see the module's steps). ``probe``: the nominal
    probe (its K is the intrinsic guess, its mount the flange-to-probe transform)."""
    size = (probe.cols_px, probe.rows_px)
    obj = board.corners_mm
    try:
        intr = [_intrinsics(probe, obj, views, cam, size, distortion) for cam in (0, 1)]
    except CalibrationError as exc:
        # A sensor too coarse to read the markers at any pose: more poses cannot help (a
        # 16-pixel sensor was told to give more, or nearer, poses).
        marker_px = board.marker_mm * float(probe.K[0, 0]) / (0.5 * sum(probe.z_range_mm))
        if marker_px < MIN_MARKER_PX:
            found = str(exc).split(";")[0]
            raise CalibrationError(f"{found}: a marker of the board spans only {marker_px:.2g} px on this "
                                   f"{probe.cols_px}x{probe.rows_px} sensor at mid-range, and reading one takes about "
                                   f"{MIN_MARKER_PX:g}, which no pose changes: calibrate at a larger resolution (the "
                                   f"probe's rows_px and cols_px)") from None
        raise
    X, Z, final, errs, std_pose, std_int, bundle = _hand_eye(obj, views, intr, distortion)
    mount_inv = rigid_inverse(probe.mount)
    normal, offset, rms, npts, nviews, scatter = _laser_plane(probe, board, views, final, X, Z, mount_inv)
    plane_std = _plane_std(probe, board, views, mount_inv, normal, scatter, bundle)
    cams = []
    models = []
    for c in (0, 1):
        K, dist = final[c]
        _, _, zhang_err, _, n_views, n_corners = intr[c]
        cams.append(CameraFit(K, dist, X[c], errs[c], zhang_err, std_int[c], std_pose[c], n_views, n_corners))
        models.append(CameraModel(K, dist, mount_inv @ X[c]))
    calibration = ProbeCalibration(tuple(models), normal, offset, source)
    wrong = calibration.implausible(probe)
    if wrong:  # (written, it would be refused where the rig is read next, pointing back here)
        raise CalibrationError(f"the fit is no calibration of this probe: {wrong}; the views taught it too "
                               f"little, or misread the board: more views, spread over the range")
    return ProbeFit(replace(probe, calibration=calibration), cams, Z, rms, npts, nviews, plane_std)


# -- 1. intrinsics ---------------------------------------------------------------------------
def _intrinsics(probe, obj, views, cam, size, distortion):
    used = [(v, v.ids[cam], v.corners[cam]) for v in views if len(v.ids[cam]) >= MIN_CORNERS]
    if len(used) < MIN_VIEWS:
        raise CalibrationError(
            f"camera {cam} found the board ({MIN_CORNERS} or more corners) in {len(used)} of {len(views)} views; "
            f"a calibration needs at least {MIN_VIEWS}: give more poses, or poses nearer the middle of the range")
    objp = [obj[ids].astype(np.float32) for _, ids, _ in used]
    imgp = [c.astype(np.float32).reshape(-1, 1, 2) for _, _, c in used]
    _check_spread(probe.K, objp, imgp, cam)
    # Distortion: k1 only. The board fills the middle of a small sensor, so higher terms (k2,
    # k3, tangential) are barely seen there and extrapolate wildly to the corners (tried: k2
    # free gave σ(k2) ≈ 1 and millimetres of error at the field's edge on the 160-pixel probe).
    flags = cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST
    if not distortion:
        flags |= cv2.CALIB_FIX_K1
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    out = cv2.calibrateCameraExtended(objp, imgp, size, probe.K.copy(), np.zeros(5), flags=flags, criteria=crit)
    err, K, dist, std_int = out[0], out[1], out[2], out[5]
    std = std_int.ravel()
    names = ("fx_px", "fy_px", "cx_px", "cy_px", "k1", "k2", "p1", "p2", "k3")
    return (K, dist.ravel()[:5], float(err), {n: float(s) for n, s in zip(names, std)}, len(used),
            int(sum(len(i) for _, i, _ in used)))


def _check_spread(K, objp, imgp, cam):
    """Zhang's method needs the board at several orientations: refuse a parallel set."""
    normals = []
    for o, i in zip(objp, imgp):
        ok, rvec, _ = cv2.solvePnP(o, i, K, None, flags=cv2.SOLVEPNP_IPPE)
        if ok:
            normals.append(cv2.Rodrigues(rvec)[0][:, 2])
    if len(normals) < 2:
        return
    n = np.array(normals)
    spread = max(math.degrees(math.acos(min(1.0, abs(float(a @ b))))) for a in n for b in n)
    if spread < MIN_SPREAD_DEG:
        raise CalibrationError(
            f"camera {cam}: the {len(n)} board poses are all parallel (their normals lie within {spread:.2f}° of "
            f"each other); a calibration needs the board seen at tilts at least {MIN_SPREAD_DEG:g}° apart, about "
            f"two different axes")


# -- 2. hand-eye -----------------------------------------------------------------------------
def _board2cam(K, dist, obj, ids, corners):
    ok, rvec, tvec = cv2.solvePnP(obj[ids], corners, K, dist, flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        return None
    return make_pose(cv2.Rodrigues(rvec)[0], tvec.ravel())


def _log_rotation(R):
    return cv2.Rodrigues(np.ascontiguousarray(R))[0].ravel()


def _park_martin(F, C):
    """X with F_j⁻¹F_i X = X C_j C_i⁻¹ for all pairs (least squares)."""
    alphas, betas, As, Bs = [], [], [], []
    n = len(F)
    for i in range(n):
        for j in range(i + 1, n):
            A = rigid_inverse(F[j]) @ F[i]
            B = C[j] @ rigid_inverse(C[i])
            a, b = _log_rotation(A[:3, :3]), _log_rotation(B[:3, :3])
            if np.linalg.norm(a) < math.radians(2.0):
                continue  # a pure translation says nothing about the rotation and little else
            alphas.append(a)
            betas.append(b)
            As.append(A)
            Bs.append(B)
    if len(alphas) < 2:
        raise CalibrationError("hand-eye: the probe must turn between views about at least two different axes "
                               "(all views have nearly the same orientation)")
    M = sum(np.outer(b, a) for a, b in zip(alphas, betas))
    w, V = np.linalg.eigh(M.T @ M)
    if w.min() <= 1e-12 * w.max():
        raise CalibrationError("hand-eye: the views turn the probe about one axis only; tilt it about two")
    R = V @ np.diag(w ** -0.5) @ V.T @ M.T
    lhs = np.concatenate([A[:3, :3] - np.eye(3) for A in As])
    rhs = np.concatenate([R @ B[:3, 3] - A[:3, 3] for A, B in zip(As, Bs)])
    t = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    return make_pose(orthonormalize(make_pose(R, t))[:3, :3], t)


def _small(T, delta):
    """T moved by delta (6,): rotation vector (rad) then translation (mm), applied in the parent frame."""
    R = cv2.Rodrigues(np.ascontiguousarray(delta[:3]))[0]
    return make_pose(R @ T[:3, :3], T[:3, 3] + delta[3:])


def _hand_eye(obj, views, intr, distortion):
    """Park–Martin per camera, then one bundle adjustment of everything: both cameras' poses
    in the flange frame, the board in the base frame and both cameras' intrinsics (and
    distortion), on the corners' reprojection error with the flange poses held as exact."""
    F_all = [np.asarray(v.flange2base, dtype=np.float64) for v in views]
    X, obs = [], []
    for c in (0, 1):
        K, dist = intr[c][0], intr[c][1]
        F, C, data = [], [], []
        for v, Fi in zip(views, F_all):
            if len(v.ids[c]) < MIN_CORNERS:
                continue
            Ci = _board2cam(K, dist, obj, v.ids[c], v.corners[c])
            if Ci is not None:
                F.append(Fi)
                C.append(Ci)
                data.append((Fi, v.ids[c], v.corners[c]))
        X.append(_park_martin(F, C))
        obs.append(data)
    # The board in the base frame, averaged over both cameras' views.
    Zs = [d[0] @ X[c] @ _board2cam(intr[c][0], intr[c][1], obj, d[1], d[2]) for c in (0, 1) for d in obs[c]]
    Z = orthonormalize(make_pose(np.mean([z[:3, :3] for z in Zs], axis=0), np.mean([z[:3, 3] for z in Zs], axis=0)))
    n_int = 5 if distortion else 4  # fx, fy, cx, cy [, k1]
    base_int = [np.concatenate([[intr[c][0][0, 0], intr[c][0][1, 1], intr[c][0][0, 2], intr[c][0][1, 2]],
                                intr[c][1][:4]])[:n_int] for c in (0, 1)]
    n_par = 18 + 2 * n_int

    def unpack(params):
        Xs = [_small(X[0], params[0:6]), _small(X[1], params[6:12])]
        Zp = _small(Z, params[12:18])
        cams = []
        for c in (0, 1):
            v = base_int[c] + params[18 + c * n_int:18 + (c + 1) * n_int]
            K = np.array([[v[0], 0.0, v[2]], [0.0, v[1], v[3]], [0.0, 0.0, 1.0]])
            dist = np.zeros(5)
            dist[:n_int - 4] = v[4:]
            cams.append((K, dist))
        return Xs, Zp, cams

    def residuals(params):
        Xs, Zp, cams = unpack(params)
        out = []
        for c in (0, 1):
            K, dist = cams[c]
            pts, seen = [], []
            for Fi, ids, corners in obs[c]:
                board2cam = rigid_inverse(Fi @ Xs[c]) @ Zp
                pts.append(obj[ids] @ board2cam[:3, :3].T + board2cam[:3, 3])
                seen.append(corners)
            proj = cv2.projectPoints(np.concatenate(pts), np.zeros(3), np.zeros(3), K, dist)[0].reshape(-1, 2)
            out.append((proj - np.concatenate(seen)).ravel())
        return out

    steps = np.concatenate([[1e-6] * 3 + [1e-4] * 3] * 3 + [[1e-4] * 4 + [1e-7] * (n_int - 4)] * 2)
    params = np.zeros(n_par)
    lam = 1e-3
    r = np.concatenate(residuals(params))
    J = None
    for _ in range(60):
        J = np.empty((len(r), n_par))
        for k in range(n_par):
            d = np.zeros(n_par)
            d[k] = steps[k]
            J[:, k] = (np.concatenate(residuals(params + d)) - np.concatenate(residuals(params - d))) / (2 * d[k])
        H, g = J.T @ J, J.T @ r
        improved = False
        while lam < 1e10:
            step = -np.linalg.solve(H + lam * np.diag(np.diag(H)), g)
            r_new = np.concatenate(residuals(params + step))
            if r_new @ r_new < r @ r:
                params, r, lam, improved = params + step, r_new, max(lam * 0.3, 1e-9), True
                break
            lam *= 10.0
        if not improved or np.abs(step).max() < 1e-10:
            break
    Xs, Zp, cams = unpack(params)
    parts = residuals(params)
    errs = [float(np.sqrt(np.mean(p ** 2))) for p in parts]
    dof = max(len(r) - n_par, 1)
    cov = (r @ r / dof) * np.linalg.pinv(J.T @ J)
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    names = ("fx_px", "fy_px", "cx_px", "cy_px", "k1")[:n_int]
    std_pose = [{"position_mm": float(np.linalg.norm(sd[6 * c + 3:6 * c + 6])),
                 "rotation_deg": float(np.degrees(np.linalg.norm(sd[6 * c:6 * c + 3])))} for c in (0, 1)]
    std_int = [{n: float(v) for n, v in zip(names, sd[18 + c * n_int:18 + (c + 1) * n_int])} for c in (0, 1)]
    return Xs, Zp, cams, errs, std_pose, std_int, (unpack, params, cov, steps)


# -- 3. laser plane --------------------------------------------------------------------------
def _laser_plane(probe, board, views, intr, X, Z, mount_inv):
    pts, nviews = [], 0
    w, h = board.pattern_mm
    inner = board.margin_mm - PLATE_EDGE_MM
    for v in views:
        F = np.asarray(v.flange2base, dtype=np.float64)
        got = 0
        for c in (0, 1):
            line = v.line[c]
            if line is None or len(line) == 0:
                continue
            K, dist = intr[c][0], intr[c][1]
            cam = CameraModel(K, dist, np.eye(4))
            # (the pattern's width w above is the edge test's, below: not these pixels' rows)
            u, v_px = cam.undistort(np.asarray(line[:, 0], float), np.asarray(line[:, 1], float))
            origin, d = cam.rays(np.column_stack([u, v_px]))
            board2cam = rigid_inverse(F @ X[c]) @ Z
            n, p0 = board2cam[:3, 2], board2cam[:3, 3]
            with np.errstate(divide="ignore", invalid="ignore"):
                t = ((p0 - origin) @ n) / (d @ n)
            ok = np.isfinite(t) & (t > 0)
            # Only the line on the plate: beyond its edges the laser falls on the table, lower.
            on_board = rigid_inverse(board2cam)
            B = (origin + np.where(ok, t, 0.0)[:, None] * d) @ on_board[:3, :3].T + on_board[:3, 3]
            ok &= ((B[:, 0] > -inner) & (B[:, 0] < w + inner) & (B[:, 1] > -inner) & (B[:, 1] < h + inner))
            P_cam = origin + t[ok, None] * d[ok]
            cam2probe = mount_inv @ X[c]
            pts.append(P_cam @ cam2probe[:3, :3].T + cam2probe[:3, 3])
            got += int(ok.sum())
        nviews += got >= MIN_LINE_POINTS
    P = np.concatenate(pts) if pts else np.zeros((0, 3))
    if nviews < 2 or len(P) < 3 * MIN_LINE_POINTS:
        raise CalibrationError(f"the laser line was found on the plate in {nviews} views ({len(P)} points); "
                               f"the laser plane needs lines at two depths or more")
    centre = P.mean(axis=0)
    _, s, Vt = np.linalg.svd(P - centre, full_matrices=False)
    if s[1] < 1e-3 * s[0]:
        raise CalibrationError("the laser lines of all views lie on one line in the probe frame; the plane needs "
                               "the plate at two depths or tilts at least")
    normal = Vt[2] * (1.0 if Vt[2][0] >= 0 else -1.0)  # towards camera 0's side (+X)
    offset = float(normal @ centre)
    resid = P @ normal - offset
    rms = float(np.sqrt(np.mean(resid ** 2)))
    # 1-σ of the plane from the point scatter: tilt from the spread of the points in the plane,
    # offset where the beam crosses mid-range.
    sigma = rms / math.sqrt(max(len(P) - 3, 1))
    tilt = math.degrees(sigma * math.sqrt(2.0) / max(s[1] / math.sqrt(len(P)), 1e-12))
    z0, z1 = probe.z_range_mm
    lever = float(np.linalg.norm(np.array([0.0, 0.0, 0.5 * (z0 + z1)]) - centre))
    offset_sd = math.hypot(sigma, math.radians(tilt) * lever)
    return normal, offset, rms, len(P), nviews, {"tilt_deg": tilt, "offset_mm": offset_sd}


def _plane_std(probe, board, views, mount_inv, normal, scatter, bundle) -> dict:
    """1-σ of the laser plane: its tilt (deg) and its offset where the beam crosses mid-range
    (mm). The plane is fitted through the plate where the bundle's poses and intrinsics put
    it, so their uncertainty (the bundle's covariance, carried through the plane fit by
    central differences) adds to the points' own scatter; the scatter alone stated a 20-view
    plane's tilt some 90 times too small."""
    unpack, params, cov, steps = bundle
    z0, z1 = probe.z_range_mm
    mid = np.array([0.0, 0.0, 0.5 * (z0 + z1)])
    e1 = np.cross(normal, [0.0, 1.0, 0.0] if abs(normal[1]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)

    def plane(p):
        Xs, Zp, cams = unpack(p)
        n, d = _laser_plane(probe, board, views, cams, Xs, Zp, mount_inv)[:2]
        return np.array([n @ e1, n @ e2, n @ mid - d])

    J = np.empty((3, len(params)))
    for k in range(len(params)):
        dp = np.zeros(len(params))
        dp[k] = steps[k]
        J[:, k] = (plane(params + dp) - plane(params - dp)) / (2 * steps[k])
    C = J @ cov @ J.T
    tilt = math.hypot(math.degrees(math.sqrt(max(C[0, 0] + C[1, 1], 0.0))), scatter["tilt_deg"])
    return {"tilt_deg": tilt, "offset_mm": math.hypot(math.sqrt(max(C[2, 2], 0.0)), scatter["offset_mm"])}


# -- against the truth -----------------------------------------------------------------------
def deviations(true_probe: Probe, calibrated: ProbeCalibration, true_distortion=()) -> dict:
    """Each calibrated parameter minus the truth: per camera f_x, f_y, c_x, c_y (px), the
    distortion coefficients, position (mm) and rotation (deg) in the probe frame; the laser
    plane's tilt (deg) and its offset (mm): where along the probe's x it crosses the beam's
    axis at mid-range (the true plane crosses at 0)."""
    true_dist = np.zeros(5)
    true_dist[:len(true_distortion)] = true_distortion
    out = {}
    for c, cam in enumerate(calibrated.cameras):
        K0, T0 = true_probe.K, true_probe.cam2probe(c)
        dT = rigid_inverse(T0) @ cam.cam2probe
        out[f"camera{c}"] = {
            "fx_px": float(cam.K[0, 0] - K0[0, 0]), "fy_px": float(cam.K[1, 1] - K0[1, 1]),
            "cx_px": float(cam.K[0, 2] - K0[0, 2]), "cy_px": float(cam.K[1, 2] - K0[1, 2]),
            "distortion": (cam.distortion - true_dist).tolist(),
            "position_mm": float(np.linalg.norm(cam.cam2probe[:3, 3] - T0[:3, 3])),
            "position_xyz_mm": (cam.cam2probe[:3, 3] - T0[:3, 3]).tolist(),
            "rotation_deg": float(np.degrees(rotation_angle(dT[:3, :3]))),
        }
    z0, z1 = true_probe.z_range_mm
    n = calibrated.plane_normal
    out["laser"] = {
        "tilt_deg": float(np.degrees(np.arccos(np.clip(abs(n[0]), 0.0, 1.0)))),
        # (calibrated minus truth like the rest: it read truth minus calibrated, the sign flipped)
        "offset_mm": float((calibrated.plane_offset_mm - n[2] * 0.5 * (z0 + z1)) / n[0]),
    }
    return out


def triangulation_error(true_probe: Probe, calibrated: Probe, true_distortion=(), n: int = 33) -> dict:
    """What a calibration does to the points, from geometry alone: points on the true laser
    plane over each camera's view (an n × n grid of pixels inside the range) imaged by the
    true camera (with its true distortion), then triangulated with the calibrated model.
    Returns {camera: {"rms_mm", "max_mm"}} and "all"."""
    true_dist = np.zeros(5)
    true_dist[:len(true_distortion)] = true_distortion
    z0, z1 = true_probe.z_range_mm
    out, every = {}, []
    for c in (0, 1):
        u, v = np.meshgrid(np.linspace(0, true_probe.cols_px - 1, n), np.linspace(0, true_probe.rows_px - 1, n))
        origin, d = true_probe.pixel_rays(np.column_stack([u.ravel(), v.ravel()]), c)
        t = -origin[0] / d[:, 0]
        P = origin + t[:, None] * d
        P = P[(P[:, 2] >= z0) & (P[:, 2] <= z1)]
        P_cam = P @ true_probe.probe2cam(c)[:3, :3].T + true_probe.probe2cam(c)[:3, 3]
        seen = cv2.projectPoints(P_cam, np.zeros(3), np.zeros(3), true_probe.K, true_dist)[0].reshape(-1, 2)
        cam = calibrated.measuring_camera(c)
        uu, vv = cam.undistort(seen[:, 0].copy(), seen[:, 1].copy())
        o, dd = cam.rays(np.column_stack([uu, vv]))
        nrm, off = calibrated.measuring_plane
        tt = (off - o @ nrm) / (dd @ nrm)
        Q = o + tt[:, None] * dd
        err = np.linalg.norm(Q - P, axis=1)
        every.append(err)
        out[f"camera{c}"] = {"rms_mm": float(np.sqrt(np.mean(err ** 2))), "max_mm": float(err.max())}
    e = np.concatenate(every)
    out["all"] = {"rms_mm": float(np.sqrt(np.mean(e ** 2))), "max_mm": float(e.max())}
    return out
