"""Robot arms as standard Denavit–Hartenberg tables (paper Section 4.1, Eq. 1–3).

Link transform (Eq. 1), θ_i = q_i + offset_i::

    T_i^{i-1} = R_Z(θ_i) · T(a_i, 0, d_i) · R_X(α_i)

A prismatic joint (a URDF's, or a gantry's) slides instead: θ_i = offset_i stays and
d_i + q_i takes d_i's place, q_i in millimetres.

Flange pose (Eq. 2) T*_DK = T_1^0 ⋯ T_6^5, tool pose (Eq. 3) T_DK = T*_DK · T_L^6.
A robot may also carry a ``base`` transform (DH frame 0 → world) for arms that are
not mounted at the world origin; by default it is the identity and the world frame
*is* the paper's robot base frame 0.

Public API (kept stable)::

    robot = load_robot("puma560")          # bundled name or path to a TOML rig
    T = robot.fk(q)                        # (6,) rad -> (4, 4) mm, world frame, tool included
    Ts = robot.fk(qs)                      # (n, 6) -> (n, 4, 4)
    frames = robot.link_frames(q)          # (7, 4, 4): DH frames 0..6 in world
    res = robot.ik(T_target, q0=None)      # IKResult (see addon.core.kinematics.ik)
    robot = robot.with_tool(T_L6)          # new Robot with tool pose T_L^6 in the flange frame
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import InputError, UnreachablePose
from ..tolerances import TOL
from .transforms import _cos_sin, check_transform, rigid_inverse

N_JOINTS = 6
# Up to this many poses, IK checks its branches by FK as a product of link matrices (fewer
# numpy calls); above, on rotation columns (fewer operations per pose).
FEW_POSES = 16

# Sanity limits for rig files. Lengths up to 1 km and joint ranges up to two turns
# each way cover every arm we know of; anything beyond is a typo or a unit error.
MAX_LENGTH_MM = 1e6
MAX_JOINT_DEG = 720.0


def _readonly(a) -> np.ndarray:
    a = np.array(a, dtype=np.float64)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Robot:
    """A 6-joint serial arm in standard DH convention. Lengths mm, angles rad.

    a_mm, d_mm, alpha_rad, theta_offset_rad : (6,) DH parameters of links 1..6
    q_min_rad, q_max_rad : (6,) joint limits, applied to q (not to θ = q + offset); for a
        prismatic joint they (and q) are millimetres
    base : (4, 4) pose of DH frame 0 in the world (identity: world = robot base)
    tool : (4, 4) pose of the tool frame in DH frame 6, the paper's T_L^6
    flange : (4, 4) the mounting flange in DH frame 6, where :meth:`with_tool` mounts a tool:
        the identity for a DH table, the tool link's pose for a URDF chain (whose DH frame 6
        is a construction, not the flange)
    link_meshes : per link, (mesh file, a trimesh, or "" for none; (4, 4) transform of the
        mesh into DH frame k) for display and, without collision_meshes, the collision
        checks; empty tuple when the rig names no meshes (see link_shapes.link_mesh)
    collision_meshes : the same for the collision checks alone (a URDF's collision geometry)
    base_mesh : (mesh file or trimesh, (4, 4) transform into DH frame 0) of the base that does
        not move (a pedestal), for display and, without base_collision_mesh, the collision
        checks (the probe and links 2–6 must not touch it); () for none
    base_collision_mesh : the same for the collision checks alone (a URDF's collision geometry)
    ik_via : where IK comes from when not from this project's solver: a
        ``ik_remote.ControllerIK`` (the robot controller over TCP/IP); None: the local solver
    joint_names, link_names : the file's own names of joints 1..6 and of the links they move
        (a URDF's), which messages quote beside the numbers; () where the rig has none (a DH table)
    """

    name: str
    a_mm: np.ndarray
    d_mm: np.ndarray
    alpha_rad: np.ndarray
    theta_offset_rad: np.ndarray
    q_min_rad: np.ndarray
    q_max_rad: np.ndarray
    base: np.ndarray = field(default_factory=lambda: np.eye(4))
    tool: np.ndarray = field(default_factory=lambda: np.eye(4))
    source: str = ""
    link_meshes: tuple = ()
    collision_meshes: tuple = ()
    base_mesh: tuple = ()
    base_collision_mesh: tuple = ()
    ik_via: object = None
    prismatic: tuple = ()  # per joint, True where it slides along z_{i-1}; () for all revolute
    flange: np.ndarray = field(default_factory=lambda: np.eye(4))
    joint_names: tuple = ()
    link_names: tuple = ()

    def __post_init__(self) -> None:
        for label in ("a_mm", "d_mm", "alpha_rad", "theta_offset_rad", "q_min_rad", "q_max_rad"):
            try:
                v = _readonly(getattr(self, label))
            except (TypeError, ValueError):
                raise InputError(f"robot {self.name!r}: {label} must be 6 numbers") from None
            if v.shape != (N_JOINTS,):
                raise InputError(f"robot {self.name!r}: {label} must have shape (6,), got {v.shape}")
            if not np.all(np.isfinite(v)):
                raise InputError(f"robot {self.name!r}: {label} contains NaN or inf: {v.tolist()}")
            object.__setattr__(self, label, v)
        bad = np.nonzero(self.q_min_rad >= self.q_max_rad)[0]
        if bad.size:
            j = int(bad[0])
            raise InputError(f"robot {self.name!r}: joint {j + 1} limits are empty "
                             f"(min {np.degrees(self.q_min_rad[j]):g}° ≥ max {np.degrees(self.q_max_rad[j]):g}°)")
        object.__setattr__(self, "base", _readonly(check_transform(self.base, f"robot {self.name!r} base")))
        object.__setattr__(self, "tool", _readonly(check_transform(self.tool, f"robot {self.name!r} tool")))
        object.__setattr__(self, "flange", _readonly(check_transform(self.flange, f"robot {self.name!r} flange")))
        slides = np.zeros(N_JOINTS, dtype=bool) if len(self.prismatic) == 0 else np.asarray(self.prismatic)
        if slides.shape != (N_JOINTS,) or slides.dtype != bool:
            raise InputError(f"robot {self.name!r}: prismatic must be 6 booleans, got {self.prismatic!r}")
        object.__setattr__(self, "prismatic", tuple(bool(v) for v in slides))
        for label in ("joint_names", "link_names"):
            names = getattr(self, label)
            if len(names) not in (0, N_JOINTS) or not all(isinstance(n, str) for n in names):
                raise InputError(f"robot {self.name!r}: {label} must be 6 names or none, got {names!r}")
            object.__setattr__(self, label, tuple(names))
        slides = slides.copy()
        slides.setflags(write=False)
        object.__setattr__(self, "_slides", slides)
        object.__setattr__(self, "has_prismatic", bool(slides.any()))
        ca, sa = _cos_sin(self.alpha_rad)
        object.__setattr__(self, "_ca", _readonly(ca))
        object.__setattr__(self, "_sa", _readonly(sa))
        links = np.zeros((N_JOINTS, 4, 4))  # T_Z(d)·T_X(a)·R_X(α) per link, for _fk_chain
        links[:, 0, 0] = 1.0
        links[:, 0, 3] = self.a_mm
        links[:, 1, 1], links[:, 1, 2] = ca, -sa
        links[:, 2, 1], links[:, 2, 2] = sa, ca
        links[:, 2, 3] = self.d_mm
        links[:, 3, 3] = 1.0
        object.__setattr__(self, "_link_constants", _readonly(links))
        object.__setattr__(self, "_base_is_identity", bool(np.array_equal(self.base, np.eye(4))))
        object.__setattr__(self, "_tool_is_identity", bool(np.array_equal(self.tool, np.eye(4))))
        object.__setattr__(self, "_base_inverse", _readonly(rigid_inverse(self.base)))
        object.__setattr__(self, "_tool_inverse", _readonly(rigid_inverse(self.tool)))
        # Sizes every IK call reads, computed once (the robot is immutable).
        shoulder = _readonly(self.base[:3, :3] @ np.array([0.0, 0.0, self.d_mm[0]]) + self.base[:3, 3])
        travel = np.where(slides, np.maximum(np.abs(self.q_min_rad), np.abs(self.q_max_rad)), 0.0)
        d_far = np.abs(self.d_mm) + travel  # a sliding joint's d reaches d + q at most
        reach = float(abs(self.a_mm[0]) + travel[0] + np.sum(np.abs(self.a_mm[1:]) + d_far[1:])
                      + np.linalg.norm(self.tool[:3, 3]))
        object.__setattr__(self, "_sizes", (shoulder, reach,
                                            max(reach, float(np.max(np.abs(np.r_[self.a_mm, self.d_mm]))), 1e-300)))

    # -- construction ---------------------------------------------------------
    def with_tool(self, tool2flange) -> "Robot":
        """A copy with tool pose ``tool2flange`` (4, 4): the paper's T_L^6, tool frame in the
        mounting flange's frame (:attr:`flange`)."""
        return replace(self, tool=self.flange @ check_transform(tool2flange, "tool transform T_L^6"))

    @property
    def tool2flange(self) -> np.ndarray:
        """The tool pose in the flange's frame (the paper's T_L^6), as :meth:`with_tool` takes
        it: :attr:`tool` is that pose in DH frame 6, the flange's own pose included."""
        return rigid_inverse(self.flange) @ self.tool

    def with_base(self, base2world) -> "Robot":
        """A copy mounted with DH frame 0 at pose ``base2world`` (4, 4) in the world."""
        return replace(self, base=check_transform(base2world, "base transform"))

    def scaled(self, factor: float) -> "Robot":
        """A copy with every length (DH a, d, base and tool offsets) multiplied by ``factor``."""
        if not np.isfinite(factor) or factor <= 0:
            raise InputError(f"scale factor must be a positive finite number, got {factor}")
        base = self.base.copy()
        base[:3, 3] *= factor
        tool = self.tool.copy()
        tool[:3, 3] *= factor
        flange = self.flange.copy()
        flange[:3, 3] *= factor
        travel = np.where(self._slides, factor, 1.0)  # a sliding joint's limits are lengths too
        return replace(self, a_mm=self.a_mm * factor, d_mm=self.d_mm * factor, base=base, tool=tool, flange=flange,
                       q_min_rad=self.q_min_rad * travel, q_max_rad=self.q_max_rad * travel)

    # -- sizes ------------------------------------------------------------------
    @property
    def shoulder_world(self) -> np.ndarray:
        """(3,) mm: point on the joint-1 axis at the height of link 1, in the world frame."""
        return self._sizes[0]

    @property
    def reach_bound_mm(self) -> float:
        """Upper bound on the tool's distance from :attr:`shoulder_world`, any q (mm).

        Triangle inequality over the chain: |a1| + Σ_{i≥2} (|a_i| + |d_i|) + |tool offset|.
        A target farther than this is unreachable whatever the joint limits.
        """
        return self._sizes[1]

    @property
    def length_scale_mm(self) -> float:
        """Characteristic length of the arm (mm): weights position against orientation."""
        return self._sizes[2]

    # -- joint vectors ----------------------------------------------------------
    def check_q(self, q, name: str = "q") -> np.ndarray:
        """Validate joint vector(s) (6,) or (n, 6) in radians; return float64."""
        try:
            q = np.asarray(q, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"{name} must be numbers (joint angles in radians)") from None
        if q.shape[-1:] != (N_JOINTS,) or q.ndim > 2:
            raise InputError(f"{name} must have shape (6,) or (n, 6), got {q.shape}")
        if not np.all(np.isfinite(q)):
            idx = np.argwhere(~np.isfinite(q))[0]
            where = ", ".join(str(int(i)) for i in idx)
            raise InputError(f"{name}[{where}] is {float(q[tuple(idx)])}: joint angles must be finite numbers (radians)")
        return q

    def within_limits(self, q, tol_rad: float = TOL.joint_limit_rad) -> np.ndarray | bool:
        """True where every joint of q (6,) or (n, 6) is inside [q_min, q_max] ± tol."""
        q = self.check_q(q)
        ok = np.all((q >= self.q_min_rad - tol_rad) & (q <= self.q_max_rad + tol_rad), axis=-1)
        return bool(ok) if q.ndim == 1 else ok

    def limit_violations(self, q) -> list[str]:
        """Human-readable list of joints of q (6,) outside their limits (empty when inside)."""
        q = self.check_q(q)
        out = []
        for j in range(N_JOINTS):
            tol = TOL.joint_limit_rad
            if not (self.q_min_rad[j] - tol <= q[j] <= self.q_max_rad[j] + tol):
                # A value a hair beyond a limit would print as the limit itself ("-180.000°
                # outside [-180°, 180°]" for a limit of -3.14159 rad): as many decimals as tell
                # them apart.
                values = (q[j], self.q_min_rad[j], self.q_max_rad[j])
                shown = np.asarray(values) if self.prismatic[j] else np.degrees(values)  # as joint_text gives them
                d = next((d for d in range(3, 9) if round(shown[0], d) not in np.round(shown[1:], d)), 8)
                value, lo, hi = (self.joint_text(j, v, f".{d}f" if k == 0 or d > 3 else "g")
                                 for k, v in enumerate(values))
                out.append(f"{self.joint_label(j)} = {value} outside [{lo}, {hi}]")
        return out

    def joint_label(self, j: int) -> str:
        """Joint j (0-based) for people: "J3", or "J3 (elbow_joint)" where the file names it."""
        return f"J{j + 1}" + (f" ({self.joint_names[j]})" if self.joint_names else "")

    def link_label(self, k: int) -> str:
        """Link k (1..6) for people: "link 3", or "link 3 (forearm_link)" where the file names it."""
        return f"link {k}" + (f" ({self.link_names[k - 1]})" if self.link_names else "")

    def joint_text(self, j: int, value: float, spec: str = "g") -> str:
        """Joint j's value (rad, or mm where it slides) for people: "12.5°" or "250 mm"."""
        return f"{value:{spec}} mm" if self.prismatic[j] else f"{np.degrees(value):{spec}}°"

    def random_q(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """(n, 6) joint vectors uniformly inside the limits."""
        return rng.uniform(self.q_min_rad, self.q_max_rad, size=(n, N_JOINTS))

    # -- forward kinematics ---------------------------------------------------
    def link_transforms(self, q) -> np.ndarray:
        """Eq. 1 for every link: q (6,) -> (6, 4, 4), q (n, 6) -> (n, 6, 4, 4)."""
        q = self.check_q(q)
        theta, d = self.joint_dh(q)
        ct, st = _cos_sin(theta)
        ca, sa = self._ca, self._sa
        A = np.zeros(q.shape + (4, 4))
        A[..., 0, 0] = ct
        A[..., 0, 1] = -st * ca
        A[..., 0, 2] = st * sa
        A[..., 0, 3] = self.a_mm * ct
        A[..., 1, 0] = st
        A[..., 1, 1] = ct * ca
        A[..., 1, 2] = -ct * sa
        A[..., 1, 3] = self.a_mm * st
        A[..., 2, 1] = sa
        A[..., 2, 2] = ca
        A[..., 2, 3] = d
        A[..., 3, 3] = 1.0
        return A

    def joint_dh(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The DH angles θ and lengths d (mm) at joint vector(s) q (..., 6)."""
        if not self.has_prismatic:
            return q + self.theta_offset_rad, np.broadcast_to(self.d_mm, q.shape)
        return (np.where(self._slides, self.theta_offset_rad, q + self.theta_offset_rad),
                np.where(self._slides, self.d_mm + q, self.d_mm))

    def link_frames(self, q) -> np.ndarray:
        """World poses of DH frames 0..6 (frame 0 = robot base, 6 = flange; no tool).

        q (6,) -> (7, 4, 4); q (n, 6) -> (n, 7, 4, 4). Millimetres.
        """
        A = self.link_transforms(q)
        out = np.empty(A.shape[:-3] + (N_JOINTS + 1, 4, 4))
        out[..., 0, :, :] = self.base
        for i in range(N_JOINTS):
            out[..., i + 1, :, :] = out[..., i, :, :] @ A[..., i, :, :]
        return out

    def flange_fk(self, q) -> np.ndarray:
        """Flange pose T*_DK (Eq. 2) in the world: (6,) -> (4, 4), (n, 6) -> (n, 4, 4)."""
        q = self.check_q(q)
        if q.ndim == 1:
            return self.link_frames(q)[-1]
        return self._fk_batch(q, with_tool=False)

    def fk(self, q) -> np.ndarray:
        """Tool pose T_DK (Eq. 3) in the world: (6,) -> (4, 4), (n, 6) -> (n, 4, 4)."""
        q = self.check_q(q)
        if q.ndim == 1:
            T = self.link_frames(q)[-1]
            return T if self._tool_is_identity else T @ self.tool
        return self._fk_batch(q, with_tool=True)

    def _fk_batch(self, q: np.ndarray, with_tool: bool) -> np.ndarray:
        """Batched Eq. 2/3 (n, 6) -> (n, 4, 4) via :meth:`_fk_columns`, whatever n: a pose's
        rounding must not depend on the batch it came in (a farm's shards and one process
        give the same cloud bit for bit)."""
        X, Y, Z, P, _, _ = self._fk_columns(q, with_tool=with_tool)
        T = np.zeros((q.shape[0], 4, 4))
        T[:, :3, 0] = X.T
        T[:, :3, 1] = Y.T
        T[:, :3, 2] = Z.T
        T[:, :3, 3] = P.T
        T[:, 3, 3] = 1.0
        return T

    def _fk_chain(self, q: np.ndarray, with_tool: bool) -> np.ndarray:
        """Eq. 2/3 for q (n, 6) as the product of the link matrices, each R_Z(θ) times the
        link's constant T_Z(d)·T_X(a)·R_X(α): about 20 numpy calls whatever n, a quarter of
        the column form's, which wins for a few poses only (its 4 × 4 products are slow per
        pose). Used by IK's checks of a single target's branches, not by :meth:`fk`."""
        th = self.joint_dh(q)[0]
        c, s = np.cos(th), np.sin(th)
        Rz = np.zeros(q.shape + (4, 4))
        Rz[..., 0, 0] = c
        Rz[..., 1, 1] = c
        Rz[..., 0, 1] = -s
        Rz[..., 1, 0] = s
        Rz[..., 2, 2] = 1.0
        Rz[..., 3, 3] = 1.0
        A = Rz @ self._link_constants
        if self.has_prismatic:
            A[..., 2, 3] += np.where(self._slides, q, 0.0)
        T = self.base @ A[:, 0]
        for i in range(1, N_JOINTS):
            T = T @ A[:, i]
        if with_tool and not self._tool_is_identity:
            T = T @ self.tool
        return T

    def _fk_columns(self, q: np.ndarray, with_tool: bool = True, record_axes: bool = False):
        """Batched FK on rotation columns; about 1.5x faster than stacked 4x4 products.

        q : (n, 6). Returns X, Y, Z, P, each (3, n): the axes and origin of the tool
        (or flange) frame in the world, and, when ``record_axes``, z (6, 3, n) and
        o (6, 3, n): axis z_{i-1} and origin o_{i-1} of DH frames 0..5 (for Jacobians).

        Per link, R <- R·R_Z(θ) mixes columns x, y; p <- p + a·x + d·z; R <- R·R_X(α)
        mixes y, z. Arrays are (3, n) so each step is a few contiguous vector ops.
        """
        n = q.shape[0]
        th = self.joint_dh(q)[0].T
        ct, st = np.cos(th), np.sin(th)
        B = self.base
        X = np.repeat(B[:3, 0:1], n, axis=1)
        Y = np.repeat(B[:3, 1:2], n, axis=1)
        Z = np.repeat(B[:3, 2:3], n, axis=1)
        P = np.repeat(B[:3, 3:4], n, axis=1)
        zs = np.empty((N_JOINTS, 3, n)) if record_axes else None
        os_ = np.empty((N_JOINTS, 3, n)) if record_axes else None
        for i in range(N_JOINTS):
            if record_axes:
                zs[i] = Z
                os_[i] = P
            c, s = ct[i], st[i]
            X, Y = c * X + s * Y, c * Y - s * X
            if self.a_mm[i] != 0.0:
                P = P + self.a_mm[i] * X
            if self.prismatic[i]:
                P = P + (self.d_mm[i] + q[:, i]) * Z
            elif self.d_mm[i] != 0.0:
                P = P + self.d_mm[i] * Z
            ca, sa = float(self._ca[i]), float(self._sa[i])
            if sa == 0.0:
                if ca < 0.0:
                    Y, Z = -Y, -Z
            elif ca == 0.0:
                Y, Z = sa * Z, -sa * Y
            else:
                Y, Z = ca * Y + sa * Z, ca * Z - sa * Y
        if with_tool and not self._tool_is_identity:
            t = self.tool
            P = P + X * t[0, 3] + Y * t[1, 3] + Z * t[2, 3]
            X, Y, Z = [X * t[0, k] + Y * t[1, k] + Z * t[2, k] for k in range(3)]
        return X, Y, Z, P, zs, os_

    # -- differential kinematics ------------------------------------------------
    def jacobian(self, q) -> np.ndarray:
        """Geometric Jacobian (6, 6) at the tool point, world frame.

        Rows 0–2: linear velocity (mm/rad); rows 3–5: angular velocity (rad/rad).
        Column i: [z_{i−1} × (p_tool − o_{i−1}); z_{i−1}], or [z_{i−1}; 0] for a sliding joint
        (mm/mm).
        """
        frames = self.link_frames(q)
        return self._jacobian_from_frames(frames)

    def _jacobian_from_frames(self, frames: np.ndarray) -> np.ndarray:
        tool = frames[-1] @ self.tool
        p = tool[:3, 3]
        z = frames[:-1, :3, 2]
        o = frames[:-1, :3, 3]
        J = np.empty((6, N_JOINTS))
        J[:3] = np.cross(z, p - o).T
        J[3:] = z.T
        if self.has_prismatic:
            J[:3, self._slides] = z[self._slides].T
            J[3:, self._slides] = 0.0
        return J

    def _scaled_jacobian(self, q, length_mm: float | None) -> np.ndarray:
        L = self.length_scale_mm if length_mm is None else float(length_mm)
        if not np.isfinite(L) or L <= 0:
            raise InputError(f"length_mm must be a positive finite number, got {length_mm}")
        J = self.jacobian(q)
        J[:3] /= L
        return J

    def manipulability(self, q, length_mm: float | None = None) -> float:
        """Yoshikawa's measure √det(J Jᵀ) of the Jacobian with linear rows divided by ``length_mm``.

        The default length is :attr:`length_scale_mm`, which makes the measure
        dimensionless and comparable between arms of different size. 0 at a singularity.
        """
        sv = np.linalg.svd(self._scaled_jacobian(q, length_mm), compute_uv=False)
        return float(np.prod(sv))

    def condition_number(self, q, length_mm: float | None = None) -> float:
        """σ_max / σ_min of the length-scaled Jacobian (see :meth:`manipulability`); inf when singular."""
        sv = np.linalg.svd(self._scaled_jacobian(q, length_mm), compute_uv=False)
        return float(sv[0] / sv[-1]) if sv[-1] > sv[0] * 1e-300 else float("inf")

    # -- inverse kinematics -------------------------------------------------------
    def ik(self, T_target, q0=None, **options):
        """Joint vector reaching tool pose ``T_target`` (4, 4, world frame); see :func:`addon.core.kinematics.ik.solve`,
        or from the robot controller where ``ik_via`` names one (``options`` are the local solver's; of
        them the controller's answer heeds ``raise_on_failure`` alone)."""
        from .ik import default_seed, solve

        if self.ik_via is not None:
            result = self.ik_via.solve(self, T_target, default_seed(self) if q0 is None else q0)
            if options.get("raise_on_failure") and not result.success:
                raise UnreachablePose(f"{self.name}: {result.message}", result)
            return result
        return solve(self, T_target, q0, **options)

    def ik_batch(self, T_targets, q0=None, **options):
        """IK for (n, 4, 4) targets at once; see :func:`addon.core.kinematics.ik.solve_batch`, or
        target by target from the robot controller where ``ik_via`` names one, as :meth:`ik`."""
        from .ik import IKBatch, _check_seeds, solve_batch

        if self.ik_via is None:
            return solve_batch(self, T_targets, q0, **options)
        T = check_transform(T_targets, "IK target poses")
        if T.ndim != 3:
            raise InputError(f"IK target poses must have shape (n, 4, 4), got {T.shape}")
        seeds = _check_seeds(self, q0, len(T))
        out = [self.ik_via.solve(self, t, s) for t, s in zip(T, seeds)]
        return IKBatch(np.array([r.q for r in out]).reshape(len(out), 6), np.array([r.success for r in out], bool),
                       np.array([r.pos_err_mm for r in out]), np.array([r.rot_err_rad for r in out]),
                       np.array([r.iterations for r in out], int), [r.message for r in out],
                       [r.reason for r in out], out[0].method if out else "controller")

    def ik_all(self, T_target, **options) -> np.ndarray:
        """Every distinct closed-form solution (k, 6), k ≤ 8, within limits; see :func:`addon.core.kinematics.ik.solve_all`."""
        from .ik import solve_all

        return solve_all(self, T_target, **options)
