"""Rig files: robots (``rigs/robots/*.toml``) and probes (``rigs/probes/*.toml``) as core models.

Each loader reads one TOML file through :mod:`addon.core.config.toml` (which names
the file, key and allowed range in every error) and builds the pure model
(:class:`~addon.core.kinematics.robot.Robot`, :class:`~addon.core.optics.probe.Probe`).
Loaded rigs are cached by path and file time, so a panel redraw reads no file.
"""

from __future__ import annotations

import functools
import os
import math
from pathlib import Path

import numpy as np

from ..errors import ConfigError, InputError
from ..kinematics.robot import MAX_JOINT_DEG, MAX_LENGTH_MM, N_JOINTS, Robot
from ..kinematics.euler import pose_to_xyz_yzz
from ..kinematics.transforms import make_pose
from ..optics.calibrated import CameraModel, ProbeCalibration
from ..optics.probe import MAX_PIXELS, MIN_PIXELS, Probe, angles_from_range, check_not_grazing
from .toml import load_toml, resolve_rig


URDF_SUFFIXES = (".urdf", ".xml")


def load_robot(name_or_path: str | Path, *, base_link: str | None = None, tool_link: str | None = None,
               package_dirs=(), urdf: bool | None = None) -> Robot:
    """Robot from ``rigs/robots/<name>.toml``, a path to such a file, or a URDF file (``.urdf``
    or ``.xml``, or any name with ``urdf=True``: the chain from ``base_link`` to ``tool_link``,
    meshes found through ``package_dirs``; see addon.core.kinematics.urdf). A xacro file is
    named as one, to be expanded first. Cached while the file is unchanged (a URDF: and the mesh
    files it names)."""
    lower = str(name_or_path).lower()
    if lower.endswith(".xacro"):
        from ..kinematics.urdf import unexpanded_xacro

        raise unexpanded_xacro(Path(name_or_path), "a xacro file")
    if urdf or (urdf is None and lower.endswith(URDF_SUFFIXES)):
        path = Path(name_or_path).expanduser()
        if not path.is_file():
            raise ConfigError(f"{path}: no such file")
        return _urdf_cached(path.resolve(), base_link, tool_link, tuple(str(Path(d).expanduser()) for d in package_dirs))
    if base_link or tool_link or package_dirs:
        raise ConfigError(f"{name_or_path}: base_link, tool_link and package_dirs apply to URDF robots only")
    path = resolve_rig("robots", name_or_path)
    return _robot_cached(path, file_stamp(path))


URDF_CACHE_SIZE = 16
_urdf_cache: dict = {}  # (path, base_link, tool_link, package_dirs) -> (file stamps, Robot)


def file_stamp(path: str | Path):
    """What tells a changed file: its time of change and size (None: it cannot be read)."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_mtime_ns, st.st_size


def urdf_mesh_files(path: str | Path) -> tuple[Path, ...]:
    """The mesh files the URDF robot last loaded from ``path`` read (empty where none is
    loaded): what else makes that robot another one when edited."""
    resolved = Path(path).expanduser().resolve()
    for (held_path, *_), (stamps, _robot) in reversed(_urdf_cache.items()):
        if held_path == resolved:
            return tuple(f for f, _ in stamps[1:])
    return ()


def _urdf_cached(path: Path, base_link, tool_link, package_dirs) -> Robot:
    """The URDF robot, read again when the file or one of the mesh files it read changed (a
    collision mesh edited while the panel is open must not leave the checks on the old one)."""
    from ..kinematics.urdf import load_urdf_robot

    key = (path, base_link, tool_link, package_dirs)
    held = _urdf_cache.get(key)
    if held is not None and all(file_stamp(f) == stamp for f, stamp in held[0]):
        _urdf_cache[key] = _urdf_cache.pop(key)  # the most recently used goes last (the oldest go first)
        return held[1]
    files: list = []
    stamp = file_stamp(path)
    robot = load_urdf_robot(path, base_link, tool_link, package_dirs, files)
    _urdf_cache.pop(key, None)
    while len(_urdf_cache) >= URDF_CACHE_SIZE:
        _urdf_cache.pop(next(iter(_urdf_cache)))  # the oldest
    _urdf_cache[key] = (((path, stamp), *((f, file_stamp(f)) for f in dict.fromkeys(files))), robot)
    return robot


def load_probe(name_or_path: str | Path) -> Probe:
    """Probe from ``rigs/probes/<name>.toml`` or a path to such a file (cached while the file is unchanged)."""
    path = resolve_rig("probes", name_or_path)
    return _probe_cached(path, file_stamp(path))


@functools.lru_cache(maxsize=64)
def _robot_cached(path: Path, stamp) -> Robot:  # stamp: file_stamp(path), what tells an edited file
    return _read_robot(path)


@functools.lru_cache(maxsize=64)
def _probe_cached(path: Path, stamp) -> Probe:
    return _read_probe(path)


def _check_link_mesh(t, mesh_path: Path, key: str = "mesh") -> None:
    """A link's mesh must be a readable triangle mesh with finite coordinates (checked when the
    rig loads, not when the scene is built)."""
    import trimesh

    try:
        mesh = trimesh.load(mesh_path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many kinds for unreadable files
        raise t.error(key, f"{mesh_path} is not a readable mesh ({type(exc).__name__}: {exc})") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise t.error(key, f"no triangles could be read from {mesh_path} (STL, OBJ, PLY, glTF)")
    if not np.isfinite(mesh.vertices).all():
        raise t.error(key, f"{mesh_path} has NaN or infinite vertex coordinates")


def _read_robot(path: Path) -> Robot:
    """Robot from ``rigs/robots/<name>.toml`` or a path to such a file.

    The file has a ``name``, a ``source`` (where the numbers come from), exactly six
    ``[[link]]`` tables with ``a_mm``, ``d_mm``, ``alpha_deg``, ``theta_offset_deg``,
    ``min_deg``, ``max_deg`` (or, with ``joint = "prismatic"``, a sliding joint whose q adds
    millimetres to d: ``min_mm``, ``max_mm``), optional ``mesh`` (+ ``[link.mesh_offset]``), and optional
    ``[base]`` and ``[tool]`` poses (``xyz_mm``, ``yzz_deg``); ``meshes_optional = true``
    draws procedural links where the mesh files are not (all) there. Raises ConfigError
    naming file, key and allowed range.
    """
    top = load_toml(path)
    name = top.string("name", default=path.stem)
    source = top.string("source", default="")
    links = top.tables("link")
    if len(links) != N_JOINTS:
        raise ConfigError(f"{path}: found {len(links)} [[link]] tables; a robot needs exactly {N_JOINTS} "
                          "(one per joint, in order from the base)")
    # meshes_optional: the link meshes are an extra (python -m headless robot-meshes) that may
    # not be installed; then the links are drawn procedurally instead of refused.
    optional = top.boolean("meshes_optional", default=False)
    missing = False
    cols: dict[str, list[float]] = {k: [] for k in ("a", "d", "alpha", "offset", "lo", "hi")}
    meshes: list[tuple[str, np.ndarray]] = []
    slides: list[bool] = []
    for t in links:
        cols["a"].append(t.number("a_mm", lo=-MAX_LENGTH_MM, hi=MAX_LENGTH_MM))
        cols["d"].append(t.number("d_mm", lo=-MAX_LENGTH_MM, hi=MAX_LENGTH_MM))
        cols["alpha"].append(t.number("alpha_deg", lo=-360.0, hi=360.0))
        cols["offset"].append(t.number("theta_offset_deg", default=0.0, lo=-360.0, hi=360.0))
        # A sliding joint (joint = "prismatic"): q is millimetres added to d_mm along z_{i-1},
        # θ stays at theta_offset_deg, and the limits are min_mm and max_mm.
        slides.append(t.string("joint", default="revolute", choices=("revolute", "prismatic")) == "prismatic")
        unit, other, top_value = ("mm", "deg", MAX_LENGTH_MM) if slides[-1] else ("deg", "mm", MAX_JOINT_DEG)
        for key in (f"min_{other}", f"max_{other}"):
            if key in t.data:  # refused here: not named among the keys this link takes
                raise t.error(key, f"a {'prismatic' if slides[-1] else 'revolute'} joint's limits are "
                                   f"min_{unit} and max_{unit}")
        lo = t.number(f"min_{unit}", lo=-top_value, hi=top_value)
        hi = t.number(f"max_{unit}", lo=-top_value, hi=top_value)
        if lo >= hi:
            raise t.error(f"max_{unit}", f"{hi:g} must be greater than min_{unit} = {lo:g}")
        cols["lo"].append(lo if slides[-1] else math.radians(lo))
        cols["hi"].append(hi if slides[-1] else math.radians(hi))
        # Display meshes (the Blender scene loads them); the path is relative to the rig file.
        mesh = ""
        if t.has("mesh"):
            mesh_path = (path.parent / t.string("mesh")).resolve()
            if mesh_path.is_file():
                _check_link_mesh(t, mesh_path)
                mesh = str(mesh_path)
            elif not optional:
                raise t.error("mesh", f"no such file: {mesh_path}")
            else:
                missing = True
        if t.has("mesh_offset") and not t.has("mesh"):
            raise t.error("mesh_offset", "places the link's mesh, and this link has none: give its mesh = \"FILE\" "
                                         "or leave the offset out")
        meshes.append((mesh, t.pose("mesh_offset")))
        t.finish()
    base = top.pose("base")
    tool = top.pose("tool")
    pedestal: tuple = ()
    if top.has("base_mesh"):
        base_path = (path.parent / top.string("base_mesh")).resolve()
        if base_path.is_file():
            _check_link_mesh(top, base_path, "base_mesh")
            pedestal = (str(base_path), np.eye(4))
        elif not optional:
            raise top.error("base_mesh", f"no such file: {base_path}")
        else:
            missing = True
    top.finish()
    if missing:
        meshes, pedestal = [], ()  # an optional set not (wholly) installed: the procedural links
    try:
        return Robot(
            name=name,
            a_mm=cols["a"],
            d_mm=cols["d"],
            alpha_rad=np.radians(cols["alpha"]),
            theta_offset_rad=np.radians(cols["offset"]),
            q_min_rad=np.array(cols["lo"]),
            q_max_rad=np.array(cols["hi"]),
            prismatic=tuple(slides),
            base=base,
            # The rig's tool plate on the flange carries whatever is mounted (the probe's mount
            # comes after it: Robot.with_tool), as a URDF's tool link does.
            tool=tool,
            flange=tool,
            source=source,
            link_meshes=tuple(meshes) if any(m for m, _ in meshes) else (),
            # An optional extra is for the eye only: the collision checks keep the procedural
            # links, so that no result depends on whether it was installed.
            collision_meshes=tuple(("", np.eye(4)) for _ in meshes) if optional and meshes else (),
            base_mesh=pedestal,
            base_collision_mesh=("", np.eye(4)) if optional and pedestal else (),
        )
    except InputError as exc:
        raise ConfigError(f"{path}: {exc}") from None


def _read_probe(path: Path) -> Probe:
    """Probe from ``rigs/probes/<name>.toml`` or a path to such a file.

    Keys: ``name``, ``source``; ``[camera]`` with ``a_mm``, ``b_mm``, either
    ``phi_deg`` and ``gamma_deg`` or ``range_mm = [z_min, z_max]`` (φ, γ then follow
    from Eq. 7), ``rows_px`` (H, along the triangulation direction) and ``cols_px``
    (W, along the line); ``[laser]`` with ``line_width_mm``, ``fan_deg``,
    ``wavelength_nm``; ``[mount]`` with ``xyz_mm``, ``yzz_deg`` (T_L^6).
    """
    top = load_toml(path)
    name = top.string("name", default=path.stem)
    source = top.string("source", default="")
    cam = top.table("camera")
    a = cam.number("a_mm", lo=0.0, hi=1e5, lo_open=True)
    b = cam.number("b_mm", default=0.0, lo=-1e5, hi=1e5)
    if cam.has("range_mm"):
        if cam.has("phi_deg") or cam.has("gamma_deg"):
            raise cam.error("range_mm", "give either range_mm or phi_deg and gamma_deg, not both")
        z = cam.numbers("range_mm", 2, lo=-1e6, hi=1e6)
        try:
            phi, gamma = angles_from_range(a, b, float(z[0]), float(z[1]))
        except InputError as exc:
            raise cam.error("range_mm", str(exc)) from None
    else:
        phi = math.radians(cam.number("phi_deg", lo=0.0, hi=90.0, lo_open=True, hi_open=True))
        gamma = math.radians(cam.number("gamma_deg", lo=0.0, hi=90.0, lo_open=True, hi_open=True))
    rows = cam.integer("rows_px", lo=MIN_PIXELS, hi=MAX_PIXELS)
    cols = cam.integer("cols_px", lo=MIN_PIXELS, hi=MAX_PIXELS)
    cam.finish()
    laser = top.table("laser", default={})
    width = laser.number("line_width_mm", default=0.3, lo=0.0, hi=100.0, lo_open=True)
    fan = laser.number("fan_deg", default=60.0, lo=0.0, hi=180.0, lo_open=True, hi_open=True)
    wavelength = laser.number("wavelength_nm", default=650.0, lo=200.0, hi=20000.0)
    laser.finish()
    mount = top.pose("mount")
    calibration = _read_calibration(top.table("calibration", default=None))
    top.finish()
    try:
        probe = Probe(name=name, a_mm=a, b_mm=b, phi_rad=phi, gamma_rad=gamma, rows_px=rows, cols_px=cols,
                      line_width_mm=width, fan_rad=math.radians(fan), wavelength_nm=wavelength, mount=mount,
                      source=source, calibration=calibration)
        check_not_grazing(probe)
        wrong = None if calibration is None else calibration.implausible(probe)
        if wrong:
            raise InputError(f"[calibration]: {wrong}: a calibration corrects its probe's design by small "
                             f"amounts, and this one is of another probe, or written wrong (python -m headless "
                             f"calibrate CONFIG --out DIR writes one)")
        return probe
    except InputError as exc:
        raise ConfigError(f"{path}: {exc}") from None


def _read_calibration(cal) -> ProbeCalibration | None:
    """``[calibration]``: ``source``; ``[calibration.camera0]`` and ``camera1`` with ``fx_px``,
    ``fy_px``, ``cx_px``, ``cy_px``, ``distortion`` (k1, k2, p1, p2, k3), the camera's pose in
    the probe frame as ``xyz_mm`` and ``rotvec_deg`` (axis times angle, OpenCV's Rodrigues
    vector, in degrees); ``[calibration.laser]`` with ``normal`` and ``offset_mm`` (the laser
    plane n·x = offset in the probe frame)."""
    if cal is None:
        return None
    import cv2

    source = cal.string("source", default="")
    cams = []
    for i in (0, 1):
        c = cal.table(f"camera{i}")
        fx = c.number("fx_px", lo=0.0, hi=1e7, lo_open=True)
        fy = c.number("fy_px", lo=0.0, hi=1e7, lo_open=True)
        cx = c.number("cx_px", lo=-1e6, hi=1e6)
        cy = c.number("cy_px", lo=-1e6, hi=1e6)
        dist = c.number_list("distortion", default=[0.0] * 5, lo=-1e6, hi=1e6)
        if len(dist) not in (4, 5):
            raise c.error("distortion", f"{len(dist)} numbers: expected 4 or 5 (k1, k2, p1, p2[, k3])")
        xyz = c.numbers("xyz_mm", 3, lo=-1e6, hi=1e6)
        rotvec = c.numbers("rotvec_deg", 3, lo=-360.0, hi=360.0)
        c.finish()
        R = cv2.Rodrigues(np.radians(rotvec))[0]
        K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
        cams.append(CameraModel(K, dist, make_pose(R, xyz)))
    laser = cal.table("laser")
    normal = laser.numbers("normal", 3, lo=-1e6, hi=1e6)
    offset = laser.number("offset_mm", lo=-1e6, hi=1e6)
    laser.finish()
    cal.finish()
    try:
        return ProbeCalibration(tuple(cams), normal, offset, source)
    except InputError as exc:
        raise laser.error("normal", str(exc)) from None


def _numbers(values) -> str:
    return "[" + ", ".join(repr(float(v)) for v in values) + "]"


def probe_toml(probe: Probe) -> str:
    """The probe as a rig file (``load_probe`` reads it back to the same numbers), its
    calibration included where it has one."""
    import cv2

    xyz, yzz = pose_to_xyz_yzz(probe.mount)
    text = [f"name = {_quoted(probe.name)}", f"source = {_quoted(probe.source)}", "",
            "[camera]", f"a_mm = {float(probe.a_mm)!r}", f"b_mm = {float(probe.b_mm)!r}",
            f"phi_deg = {float(math.degrees(probe.phi_rad))!r}", f"gamma_deg = {float(math.degrees(probe.gamma_rad))!r}",
            f"rows_px = {probe.rows_px}", f"cols_px = {probe.cols_px}", "",
            "[laser]", f"line_width_mm = {float(probe.line_width_mm)!r}", f"fan_deg = {float(math.degrees(probe.fan_rad))!r}",
            f"wavelength_nm = {float(probe.wavelength_nm)!r}", "",
            "[mount]", f"xyz_mm = {_numbers(xyz)}", f"yzz_deg = {_numbers(np.degrees(yzz))}"]
    cal = probe.calibration
    if cal is not None:
        text += ["", "# What the calibration found: triangulation uses these, rendering the true geometry above.",
                 "[calibration]", f"source = {_quoted(cal.source)}"]
        for i, cam in enumerate(cal.cameras):
            K, T = cam.K, cam.cam2probe
            rotvec = np.degrees(cv2.Rodrigues(np.ascontiguousarray(T[:3, :3]))[0].ravel())
            text += ["", f"[calibration.camera{i}]", f"fx_px = {float(K[0, 0])!r}", f"fy_px = {float(K[1, 1])!r}",
                     f"cx_px = {float(K[0, 2])!r}", f"cy_px = {float(K[1, 2])!r}", f"distortion = {_numbers(cam.distortion)}",
                     f"xyz_mm = {_numbers(T[:3, 3])}", f"rotvec_deg = {_numbers(rotvec)}"]
        text += ["", "[calibration.laser]", f"normal = {_numbers(cal.plane_normal)}",
                 f"offset_mm = {float(cal.plane_offset_mm)!r}"]
    return "\n".join(text) + "\n"


def _quoted(text: str) -> str:
    """``text`` as a TOML basic string. (JSON's escapes are TOML's too, except that JSON writes
    a character beyond U+FFFF as two surrogates, which TOML refuses: a probe named with an
    emoji was written into a file nothing could read.)"""
    out = []
    for ch in text:
        code = ord(ch)
        if ch in '"\\':
            out.append("\\" + ch)
        elif code < 0x20 or code == 0x7F:
            out.append({"\n": "\\n", "\t": "\\t", "\r": "\\r"}.get(ch, f"\\u{code:04X}"))
        elif 0xD800 <= code <= 0xDFFF:  # a lone surrogate (from a file name read with surrogateescape)
            out.append("\uFFFD")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'
