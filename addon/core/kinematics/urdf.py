"""URDF robots: the serial chain of a URDF file as a Robot, with its meshes.

The file is read with yourdfpy. The chain runs from a base link (default: the root)
to a tool link (default: the one leaf of the tree); its joints must be six revolute,
continuous or prismatic joints, with any number of fixed joints between them (planar
and floating joints are refused). Revolute and prismatic joints must give
``<limit lower upper>``, as the URDF specification requires; continuous joints get ±2π.
Joint origins and axes must be finite numbers. Lengths in URDF are metres; here they
become millimetres, a prismatic joint's position and limits too.

Every serial chain of revolute and prismatic joints has a standard Denavit–Hartenberg
description (a prismatic joint slides d along z_{i−1} instead of turning θ about it)
plus a base and a tool transform, so a URDF robot *is* a DH Robot: batched FK, the
closed forms where the geometry qualifies (a UR-type URDF gets the UR closed form),
damped least squares otherwise, limits, collision checks and the Blender rig all work
unchanged. The table is found from the joint axes at q = 0, as lines in space:

- z_{i−1} is joint i's axis (its URDF direction, so that q turns the same way);
- x_i runs along the common normal from axis i to axis i + 1, and frame i's origin
  is where that normal meets axis i + 1; for parallel axes the normal through frame
  i − 1's origin is taken, for intersecting ones x_i = z_{i−1} × z_i;
- a_i, α_i, d_i and θ_i's offset are read off those frames; frame 0 lies on axis 1
  with x_0 = x_1, frame 6 on axis 6 with x_6 = x_5, and the base and tool transforms
  take up the rest.

The conversion is checked against the URDF's own chain product at random joint
vectors when the file loads (1e-6 mm; a failure is reported, never used).

Meshes: every link's visuals (and, separately, its collision geometry) go to the DH
link whose joint moves it, those of the base link and the links fixed to it to the
robot's base (DH frame 0), links off the chain nowhere: mesh files (STL,
OBJ, DAE, ...; ``package://`` resolved against ``package_dirs`` and the file's folder)
with their scale, and boxes, cylinders and spheres.
"""

from __future__ import annotations

from collections import Counter

from pathlib import Path

import numpy as np

from ..errors import ConfigError, InputError
from .robot import MAX_JOINT_DEG, MAX_LENGTH_MM, N_JOINTS, Robot
from .transforms import rigid_inverse

M_TO_MM = 1000.0
MOVING = ("revolute", "continuous", "prismatic")
ROS_FLANGE = "tool0"  # ROS-Industrial's name for the flange frame (z out of the flange): the tool link where the chain ends in several
PARALLEL_TOL = 1e-9  # |u × v| below this: parallel axes
MEET_TOL_MM = 1e-9   # common normal shorter than this: the axes meet
FAR_NORMAL_MM = 1e4  # a common normal farther than this from the axes' points (10 m): nearly parallel axes


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    k = axis / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    T = np.eye(4)
    T[:3, :3] = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    return T


def _in_mm(T: np.ndarray) -> np.ndarray:
    T = np.array(T, dtype=np.float64)
    T[:3, 3] *= M_TO_MM
    return T


def _origin(joint) -> np.ndarray:
    return np.eye(4) if joint.origin is None else _in_mm(joint.origin)


class UrdfChain:
    """The joints from the base link to the tool link of a parsed URDF: ``joints`` (six
    movable ones and the fixed ones between, in order), world poses at q = 0 (mm)."""

    def __init__(self, urdf, path: Path, base_link: str | None, tool_link: str | None):
        robot = urdf.robot
        for kind, names in (("link", [link.name for link in robot.links]), ("joint", [j.name for j in robot.joints])):
            counts = Counter(names)
            twice = sorted(n for n, k in counts.items() if k > 1)
            if twice:
                raise ConfigError(f"{path}: {kind} {twice[0]!r} is defined {counts[twice[0]]} times; each {kind} "
                                  f"needs a name of its own")
        links = {link.name for link in robot.links}
        parent_joint = {}
        children: dict[str, list] = {}
        for j in robot.joints:
            for end in (j.parent, j.child):
                if end not in links:
                    raise ConfigError(f"{path}: joint {j.name!r} names link {end!r}, which the file does not define")
            if j.child in parent_joint:
                raise ConfigError(f"{path}: link {j.child!r} is the child of two joints; a robot is a tree")
            parent_joint[j.child] = j
            children.setdefault(j.parent, []).append(j)
        roots = sorted(links - set(parent_joint))
        if len(roots) != 1:
            raise ConfigError(f"{path}: the links form {len(roots)} trees (roots {', '.join(roots) or 'none'}); "
                              "a robot has one root")
        base = base_link or roots[0]
        if base not in links:
            raise ConfigError(f"{path}: base_link {base!r} is not a link of this file "
                              f"(links: {', '.join(sorted(links))})")
        if tool_link is None:
            leaves = sorted(name for name in _descendants(base, children) if name not in children)
            if len(leaves) > 1 and ROS_FLANGE in leaves:
                leaves = [ROS_FLANGE]  # ROS-Industrial's flange frame, where tools are mounted
            if len(leaves) != 1:
                raise ConfigError(f"{path}: the chain from {base!r} ends in {len(leaves)} links "
                                  f"({', '.join(leaves)}); name the tool link (tool_link = ...)")
            tool_link = leaves[0]
        if tool_link not in links:
            raise ConfigError(f"{path}: tool_link {tool_link!r} is not a link of this file "
                              f"(links: {', '.join(sorted(links))})")
        chain = []
        link = tool_link
        seen = set()
        while link != base:
            if link not in parent_joint:
                raise ConfigError(f"{path}: link {tool_link!r} does not hang below {base!r}")
            if link in seen:  # (the walk up from the tool went round for ever)
                raise ConfigError(f"{path}: the joints above {tool_link!r} form a cycle through link {link!r}; "
                                  f"a robot's links form a tree")
            seen.add(link)
            chain.append(parent_joint[link])
            link = parent_joint[link].parent
        chain.reverse()
        for j in chain:
            if j.type not in MOVING + ("fixed",):
                raise ConfigError(f"{path}: joint {j.name!r} is {j.type}; the chain may hold revolute, continuous, "
                                  "prismatic and fixed joints only")
            if j.mimic is not None:
                raise ConfigError(f"{path}: joint {j.name!r} mimics another joint; that is not supported")
        moving = [j for j in chain if j.type in MOVING]
        if len(moving) != N_JOINTS:
            raise ConfigError(f"{path}: the chain from {base!r} to {tool_link!r} has {len(moving)} moving joints "
                              f"({', '.join(j.name for j in moving) or 'none'}); a robot here has exactly {N_JOINTS}")
        self.path, self.base, self.tool_link = path, base, tool_link
        self.joints, self.moving, self.children = chain, moving, children
        # World poses at q = 0: each joint's frame (its axis lies there) and each link's.
        self.link_pose = {base: np.eye(4)}
        self.link_index = {base: 0}  # the DH link a URDF link moves with (0: the base)
        self.axis_point, self.axis_dir = [], []
        count = 0
        for j in chain:
            J = self.link_pose[j.parent] @ _origin(j)
            if j.type in MOVING:
                axis = np.asarray(j.axis if j.axis is not None else (1.0, 0.0, 0.0), dtype=np.float64)
                if not np.isfinite(axis).all() or np.linalg.norm(axis) < 1e-12:
                    raise ConfigError(f"{path}: joint {j.name!r} has no usable axis ({axis.tolist()})")
                self.axis_point.append(J[:3, 3])
                self.axis_dir.append(J[:3, :3] @ (axis / np.linalg.norm(axis)))
                count += 1
            self.link_pose[j.child] = J
            self.link_index[j.child] = count
        # Links hanging on chain links by fixed joints only move with them (a camera, a flange).
        for name in list(self.link_pose):
            self._attach_fixed(name)

    def _attach_fixed(self, name: str) -> None:
        for j in self.children.get(name, []):
            if j.child not in self.link_pose and j.type == "fixed":
                self.link_pose[j.child] = self.link_pose[name] @ _origin(j)
                self.link_index[j.child] = self.link_index[name]
                self._attach_fixed(j.child)

    def limits(self) -> tuple[np.ndarray, np.ndarray]:
        """Each moving joint's (lower, upper): radians, or mm where it slides. The URDF
        specification makes <limit> compulsory for revolute and prismatic joints, so one
        without it (or without lower and upper) is refused; continuous joints have none and
        get ±2π (±360°)."""
        lo, hi = [], []
        for j in self.moving:
            if j.type == "continuous":
                lo.append(-2 * np.pi)
                hi.append(2 * np.pi)
                continue
            if j.limit is None or j.limit.lower is None or j.limit.upper is None:
                what = ("metres" if j.type == "prismatic" else
                        'radians; or type="continuous" for a joint that turns without limits, which gets ±360°')
                raise ConfigError(f"{self.path}: {j.type} joint {j.name!r} has no limits; a {j.type} joint needs "
                                  f'<limit lower="..." upper="..."/> ({what})')
            unit = M_TO_MM if j.type == "prismatic" else 1.0
            lo.append(float(j.limit.lower) * unit)
            hi.append(float(j.limit.upper) * unit)
        lo, hi = np.array(lo), np.array(hi)
        bad = np.nonzero(~(np.isfinite(lo) & np.isfinite(hi)) | (lo >= hi))[0]
        if bad.size:
            j = self.moving[int(bad[0])]
            raise ConfigError(f"{self.path}: joint {j.name!r} has limits [{lo[bad[0]]}, {hi[bad[0]]}]; "
                              "lower must be below upper, both finite")
        # As the DH rigs' tables allow: ±720° for a turning joint, ±1 km for a sliding one.
        top = np.where(self.prismatic, MAX_LENGTH_MM, np.radians(MAX_JOINT_DEG))
        bad = np.nonzero(np.maximum(np.abs(lo), np.abs(hi)) > top)[0]
        if bad.size:
            i = int(bad[0])
            j = self.moving[i]
            allowed = (f"within ±{MAX_LENGTH_MM / M_TO_MM:g} m" if self.prismatic[i] else
                       f"within ±{np.radians(MAX_JOINT_DEG):.4g} rad (±{MAX_JOINT_DEG:g}°)")
            raise ConfigError(f"{self.path}: joint {j.name!r} has limits [{float(j.limit.lower):g}, "
                              f"{float(j.limit.upper):g}]; give them {allowed} (a unit slip?)")
        return lo, hi

    @property
    def prismatic(self) -> tuple[bool, ...]:
        return tuple(j.type == "prismatic" for j in self.moving)

    def fk(self, q: np.ndarray) -> np.ndarray:
        """The tool link's world pose (mm) at joint vector q (6,; rad, or mm where a joint
        slides), by the URDF's own product."""
        T = np.eye(4)
        k = 0
        for j in self.joints:
            T = T @ _origin(j)
            if j.type in MOVING:
                axis = np.asarray(j.axis if j.axis is not None else (1.0, 0.0, 0.0), dtype=np.float64)
                if j.type == "prismatic":
                    slide = np.eye(4)
                    slide[:3, 3] = axis / np.linalg.norm(axis) * q[k]
                    T = T @ slide
                else:
                    T = T @ _axis_angle(axis, q[k])
                k += 1
        return T


def _descendants(link: str, children: dict) -> list[str]:
    """``link`` and every link below it (iteratively, each once: a cycle ended in RecursionError)."""
    out, todo, seen = [], [link], set()
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        out.append(name)
        todo.extend(j.child for j in reversed(children.get(name, [])))
    return out


def _frame(x: np.ndarray, z: np.ndarray, o: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, np.cross(z, x), z, o
    return T


def _perpendicular(z: np.ndarray) -> np.ndarray:
    x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
    return x / np.linalg.norm(x)


def dh_from_axes(points, dirs, tool_pose: np.ndarray, names=None):
    """Standard DH (a, d, α, θ offset; mm, rad), base and tool transforms for six joint axes
    (lines through ``points`` along ``dirs``, world, q = 0) and the tool's pose at q = 0.
    Two neighbouring axes nearly parallel, whose common normal lies farther than
    ``FAR_NORMAL_MM`` away, are an InputError naming them (``names``: the joints')."""
    z = [d / np.linalg.norm(d) for d in dirs]
    p = [np.asarray(v, dtype=np.float64) for v in points]
    n = len(z)
    # Frame i (0-based) has z along joint i+1's axis; its origin o[i] and x axis x[i].
    o: list = [None] * n
    x: list = [None] * n
    for i in range(n - 1):
        u, v = z[i], z[i + 1]
        c = np.cross(u, v)
        if np.linalg.norm(c) > PARALLEL_TOL:
            w = p[i] - p[i + 1]  # the common normal's feet on both axes
            b, du, dv = u @ v, u @ w, v @ w
            den = 1.0 - b * b
            with np.errstate(divide="ignore", invalid="ignore"):  # den 0 in floating point: far, below
                foot_u = p[i] + (b * dv - du) / den * u
                foot_v = p[i + 1] + (dv - b * du) / den * v
            far = max(np.linalg.norm(foot_u - p[i]), np.linalg.norm(foot_v - p[i + 1]))
            if not far <= FAR_NORMAL_MM:
                joints = (f"joints {names[i]!r} and {names[i + 1]!r}" if names is not None else
                          f"joint axes {i + 1} and {i + 2}")
                angle = np.degrees(np.arctan2(np.linalg.norm(c), abs(b)))
                raise InputError(f"{joints} are {angle:.2g}° from parallel, so the common normal of their axes "
                                 f"lies {f'{far / 1000.0:.3g} m away' if np.isfinite(far) else 'too far away to compute'}: a DH table (this simulator's robot model) "
                                 f"holds such a pair only with lengths of that size. Make the two axes parallel "
                                 f"in the file, or turn them further apart")
            gap = foot_v - foot_u
            # The common normal runs along u × v: exact, where the feet's difference is rounding
            # noise for axes nearly parallel.
            x_next = c / np.linalg.norm(c)
            if gap @ x_next < 0.0:
                x_next = -x_next
        else:  # parallel: the normal through this frame's origin (collinear: none)
            foot_u = p[i] if o[i] is None else o[i]
            foot_v = p[i + 1] + ((foot_u - p[i + 1]) @ v) * v
            gap = foot_v - foot_u
            x_next = gap / np.linalg.norm(gap) if np.linalg.norm(gap) > MEET_TOL_MM else None
        if o[i] is None:
            o[i] = foot_u  # frame 0: on axis 1, at its common normal with axis 2
        o[i + 1], x[i + 1] = foot_v, x_next
    x[0] = x[1] if x[1] is not None else _perpendicular(z[0])
    for i in range(1, n):  # collinear neighbours: carry the x axis over
        if x[i] is None:
            x[i] = x[i - 1] - (x[i - 1] @ z[i]) * z[i]
            x[i] /= np.linalg.norm(x[i])
    frames = [_frame(x[i], z[i], o[i]) for i in range(n)]
    # Frame 6 on axis 6 at the tool's foot, x_6 = x_5.
    o6 = o[n - 1] + ((tool_pose[:3, 3] - o[n - 1]) @ z[n - 1]) * z[n - 1]
    frames.append(_frame(x[n - 1], z[n - 1], o6))
    a, d, alpha, theta = (np.zeros(n) for _ in range(4))
    for i in range(n):
        F0, F1 = frames[i], frames[i + 1]
        z0, x0, x1, z1 = F0[:3, 2], F0[:3, 0], F1[:3, 0], F1[:3, 2]
        delta = F1[:3, 3] - F0[:3, 3]
        d[i] = delta @ z0
        a[i] = delta @ x1
        alpha[i] = np.arctan2(np.cross(z0, z1) @ x1, z0 @ z1)
        theta[i] = np.arctan2(np.cross(x0, x1) @ z0, x0 @ x1)
    return a, d, alpha, theta, frames[0], rigid_inverse(frames[-1]) @ tool_pose


def load_urdf_robot(path: str | Path, base_link: str | None = None, tool_link: str | None = None,
                    package_dirs=(), files_read: list | None = None) -> Robot:
    """A Robot from a URDF file (see the module's docstring). Problems are ConfigErrors that
    name the file and what is wrong. The mesh files it reads are appended to ``files_read``
    (a cache of the robot is stale once one of them changes)."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: no such file")
    urdf = _parse(path, package_dirs)
    chain = UrdfChain(urdf, path, base_link, tool_link)
    tool_pose = chain.link_pose[chain.tool_link]
    try:
        a, d, alpha, theta, base, tool = dh_from_axes(chain.axis_point, chain.axis_dir, tool_pose,
                                                      [j.name for j in chain.moving])
    except InputError as exc:
        raise ConfigError(f"{path}: {exc}") from None
    lo, hi = chain.limits()
    try:
        robot = Robot(name=f"{urdf.robot.name or path.stem} (URDF)", a_mm=a, d_mm=d, alpha_rad=alpha, theta_offset_rad=theta,
                      q_min_rad=lo, q_max_rad=hi, base=base, tool=tool, flange=tool, source=f"URDF {path}",
                      prismatic=chain.prismatic, joint_names=tuple(j.name for j in chain.moving),
                      link_names=tuple(j.child for j in chain.moving))
    except InputError as exc:
        raise ConfigError(f"{path}: {exc}") from None
    _check_conversion(robot, chain)
    (visual, base_visual), (collision, base_collision) = _meshes(urdf, chain, robot, package_dirs, files_read)
    from dataclasses import replace

    return replace(robot, link_meshes=visual, collision_meshes=collision, base_mesh=base_visual,
                   base_collision_mesh=base_collision)


def unexpanded_xacro(path: Path, what: str = "holds xacro macros") -> ConfigError:
    """The refusal of a xacro file (``what``: by its name, or by the macros left in it), naming
    the command that expands it."""
    return ConfigError(f"{path}: {what}, which URDF readers do not expand: expand it first "
                       f"(ROS's `xacro {Path(path).name} > robot.urdf`) and give the result")


def _parse(path: Path, package_dirs):
    try:
        from yourdfpy import URDF
    except ImportError:
        raise ConfigError(f"{path}: reading URDF files needs the yourdfpy package, which the headless set-up "
                          "and the Blender extension install; this Python has none") from None
    import xml.etree.ElementTree as ET

    try:  # well-formed XML first: the URDF parser would quietly recover from a cut file
        tree = ET.parse(path)
    except (ET.ParseError, OSError, UnicodeDecodeError) as exc:
        try:  # a xacro: prefix without its namespace declared does not parse
            unexpanded = b"<xacro:" in path.read_bytes()
        except OSError:
            unexpanded = False
        raise (unexpanded_xacro(path) if unexpanded else
               ConfigError(f"{path}: not a readable URDF file (XML: {exc})")) from None
    # Macros left in (comments are gone: xacro's own output keeps them, and is fine): xacro's
    # elements, and ${...} or $(...) in a value.
    for element in tree.iter():
        if "xacro" in element.tag or any("${" in v or "$(" in v for v in element.attrib.values()):
            raise unexpanded_xacro(path)
    _check_names(tree.getroot(), path)
    _check_joint_numbers(tree.getroot(), path)
    _check_geometry_elements(tree.getroot(), path)
    try:
        return URDF.load(str(path), build_scene_graph=False, load_meshes=False, load_collision_meshes=False,
                         filename_handler=lambda name: name)
    except Exception as exc:  # lxml and yourdfpy raise many kinds for a malformed file
        raise ConfigError(f"{path}: not a readable URDF file ({type(exc).__name__}: {exc})") from None


JOINT_VECTORS = (("origin", "xyz", "metres"), ("origin", "rpy", "radians"), ("axis", "xyz", "a direction"))


def _check_joint_numbers(root, path: Path) -> None:
    """Every joint's origin xyz and rpy and its axis as written: three finite numbers each,
    so that a NaN is named where the user wrote it, not in the DH table derived from it."""
    for joint in root.findall("joint"):
        name = joint.get("name", "?")
        for tag in ("parent", "child"):  # (yourdfpy's own words for these were an AttributeError's)
            element = joint.find(tag)
            if element is None or not element.get("link"):
                raise ConfigError(f"{path}: joint {name!r} has no <{tag} link=\"...\"/>; every joint names its "
                                  f"parent and its child link")
        for tag, attribute, unit in JOINT_VECTORS:
            element = joint.find(tag)
            text = None if element is None else element.get(attribute)
            if text is None:
                continue
            words = text.split()
            where = f"{path}: joint {name!r} {tag} {attribute}"
            for word in words:
                try:
                    value = float(word)
                except ValueError:
                    value = float("nan")
                if not np.isfinite(value):
                    raise ConfigError(f"{where}: {word!r} is not a finite number; give three finite numbers ({unit})")
                if attribute == "xyz" and tag == "origin" and abs(value) * M_TO_MM > MAX_LENGTH_MM:
                    raise ConfigError(f"{where}: {word} is beyond ±{MAX_LENGTH_MM / M_TO_MM:g} m (the DH rigs' limit "
                                      f"on lengths); give the offset in metres (a unit slip?)")
            if len(words) != 3:
                raise ConfigError(f"{where}: {text.strip()!r} has {len(words)} numbers; give three ({unit})")


# What each shape of a <geometry> must give (the URDF specification's required attributes).
SHAPE_ATTRIBUTES = {"box": ("size",), "cylinder": ("radius", "length"), "sphere": ("radius",), "mesh": ("filename",)}


def _check_names(root, path: Path) -> None:
    """The root is a named <robot>, every link and joint has a name and every joint a type (a
    KeyError's or a None's words from yourdfpy otherwise)."""
    if root.tag != "robot":
        raise ConfigError(f"{path}: not a URDF file: its root element is <{root.tag}>, where a URDF's is <robot>")
    if not (root.get("name") or "").strip():
        raise ConfigError(f"{path}: the <robot> has no name; a URDF's robot needs name=\"...\"")
    # (The robot's own links and joints: a <transmission> names joints too, without a type.)
    for kind in ("link", "joint"):
        for i, element in enumerate(root.findall(kind)):
            if not (element.get("name") or "").strip():
                raise ConfigError(f"{path}: <{kind}> number {i + 1} has no name; every link and joint needs "
                                  f"name=\"...\"")
    for joint in root.findall("joint"):
        if not joint.get("type"):
            raise ConfigError(f"{path}: joint {joint.get('name')!r} has no type; give type=\"revolute\", "
                              f"\"continuous\", \"prismatic\" or \"fixed\"")


def _check_geometry_elements(root, path: Path) -> None:
    """Every visual and collision holds a <geometry> with exactly one shape in it, with the
    attributes that shape needs (a TypeError's or KeyError's words from yourdfpy otherwise, or
    the second shape dropped without a word)."""
    for link in root.findall("link"):
        where = f"{path}: link {link.get('name', '?')!r}"
        for kind in ("visual", "collision"):
            for item in link.findall(kind):
                geometry = item.find("geometry")
                shapes = [] if geometry is None else list(geometry)
                if len(shapes) != 1:
                    raise ConfigError(f"{where} has a <{kind}> with {len(shapes) or 'no'} shape"
                                      f"{'s' if len(shapes) > 1 else ''} in its <geometry>: give one (box, cylinder, "
                                      f"sphere or mesh), and a <{kind}> of its own for each further shape")
                shape = shapes[0]
                if shape.tag not in SHAPE_ATTRIBUTES:
                    continue  # yourdfpy's own words name an unknown shape
                missing = [a for a in SHAPE_ATTRIBUTES[shape.tag] if not (shape.get(a) or "").strip()]
                if missing:
                    raise ConfigError(f"{where}: the <{shape.tag}> of a <{kind}> has no {missing[0]}; a {shape.tag} "
                                      f"needs {' and '.join(SHAPE_ATTRIBUTES[shape.tag])}")


def _check_conversion(robot: Robot, chain: UrdfChain) -> None:
    rng = np.random.default_rng(0)
    for q in robot.random_q(8, rng):
        err = np.abs(robot.fk(q) - chain.fk(q))
        if err[:3, 3].max() > 1e-6 or err[:3, :3].max() > 1e-9:
            raise ConfigError(f"{chain.path}: the chain's DH form does not reproduce it ({err[:3, 3].max():.3g} mm "
                              "off); please report this file")


def resolve_mesh_file(name: str, urdf_path: Path, package_dirs=()) -> Path:
    """A URDF mesh reference as a file: ``package://pkg/rest`` under a folder of ``package_dirs``
    (as ``<dir>/pkg/rest`` or ``<dir>/rest``), ``file://`` and relative paths against the URDF's
    folder."""
    if name.startswith("package://"):
        rest = name[len("package://"):]
        package, _, inner = rest.partition("/")
        tried = []
        for folder in [*map(Path, package_dirs), urdf_path.parent, urdf_path.parent.parent]:
            for candidate in (folder / package / inner, folder / inner):
                tried.append(str(candidate))
                if candidate.is_file():
                    return candidate
        raise ConfigError(f"{urdf_path}: mesh {name} not found (looked in {', '.join(tried[:4])}"
                          f"{', ...' if len(tried) > 4 else ''}); give the package's parent folder in package_dirs")
    if name.startswith("file://"):
        name = name[len("file://"):]
    p = Path(name)
    p = p if p.is_absolute() else urdf_path.parent / p
    if not p.is_file():
        raise ConfigError(f"{urdf_path}: mesh {name} not found ({p})")
    return p


def _geometry_mesh(geometry, urdf_path: Path, package_dirs, files_read: list | None = None):
    """A URDF geometry as a trimesh in its own frame, metres (None: nothing drawable); a mesh
    file it reads is appended to ``files_read``."""
    import trimesh

    if geometry.mesh is not None:
        file = resolve_mesh_file(geometry.mesh.filename, urdf_path, package_dirs)
        if files_read is not None:
            files_read.append(file)
        try:
            mesh = trimesh.load(file, force="mesh", process=False)
        except Exception as exc:
            raise ConfigError(f"{urdf_path}: mesh {file} is not readable ({type(exc).__name__}: {exc})") from None
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0 or not np.isfinite(mesh.vertices).all():
            raise ConfigError(f"{urdf_path}: mesh {file} holds no usable triangles (empty, or NaN coordinates)")
        if file.suffix.lower() == ".dae" and mesh.units:
            # A COLLADA file states its unit (<asset><unit meter="0.001"/>: millimetres), which
            # RViz and Gazebo apply; the URDF's scale comes on top. (STL and OBJ state none.)
            try:
                mesh.convert_units("meters")
            except Exception as exc:  # a unit trimesh cannot read
                raise ConfigError(f"{urdf_path}: mesh {file} gives its unit as {mesh.units!r}, which cannot be "
                                  f"converted to metres ({exc})") from None
        if geometry.mesh.scale is not None:
            factors = _sizes(geometry.mesh.scale, (1, 3), f"mesh {file}'s scale", urdf_path)
            mesh.apply_transform(np.diag(np.r_[np.broadcast_to(factors, 3), 1.0]))
        return mesh
    # Sizes finite and above zero (a cylinder of radius 0 made a mesh without faces, on which
    # the collision library crashed the process; a sphere of radius 0 or a box of two sizes
    # gave tracebacks)
    if geometry.box is not None:
        return trimesh.creation.box(_sizes(geometry.box.size, (3,), "a box's size", urdf_path))
    if geometry.cylinder is not None:
        radius, length = _sizes([geometry.cylinder.radius, geometry.cylinder.length], (2,),
                                "a cylinder's radius and length", urdf_path)
        return trimesh.creation.cylinder(radius=radius, height=length, sections=32)
    if geometry.sphere is not None:
        (radius,) = _sizes([geometry.sphere.radius], (1,), "a sphere's radius", urdf_path)
        return trimesh.creation.icosphere(subdivisions=2, radius=radius)
    return None


def _sizes(values, counts: tuple, what: str, urdf_path: Path) -> np.ndarray:
    """``values`` as finite sizes above zero, as many as one of ``counts``; ConfigError naming
    ``what`` otherwise."""
    try:
        a = np.asarray(values, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        a = np.zeros(0)
    if a.size not in counts or not np.isfinite(a).all() or not (a > 0).all():
        shown = values if isinstance(values, (int, float, str)) else list(np.asarray(values, dtype=object).reshape(-1))
        raise ConfigError(f"{urdf_path}: {what} must be {' or '.join(map(str, counts))} finite number(s) above zero, "
                          f"got {shown}")
    return a


def _meshes(urdf, chain: UrdfChain, robot: Robot, package_dirs, files_read: list | None = None) -> tuple[tuple, tuple]:
    """((visuals per DH link 1..6, the base's visuals), (the same for the collision geometry)),
    each merged into one mesh in the DH frame of its link (the base: frame 0), mm; per link
    ("", identity) where it has none, () where no link has any. A link without collision
    geometry of its own is checked with its visual one, where it has that. The base is the base link and
    what hangs on it by fixed joints (a pedestal, a gantry's frame): it never moves, and the
    probe and the links must not run into it. Links off the chain are left out."""
    import trimesh

    frames0 = robot.link_frames(np.zeros(N_JOINTS))
    scale = np.diag([M_TO_MM, M_TO_MM, M_TO_MM, 1.0])
    out = []
    visual_pieces: list[list] = []
    for kind in ("visuals", "collisions"):
        pieces: list[list] = [[] for _ in range(N_JOINTS + 1)]  # the base first, then links 1..6
        for link in urdf.robot.links:
            k = chain.link_index.get(link.name)
            if k is None:
                continue  # not on the chain, nor fixed to it
            # Each URDF link's own collision geometry, or without any its visual one (by DH link,
            # a link fixed to another that had some lost its own body: a flange's 10 mm box stood
            # for the whole wrist; on the base, a pedestal drawn only beside a base link with a
            # collision body was never checked)
            items = link.visuals if kind == "visuals" else (link.collisions or link.visuals)
            for item in items:
                mesh = _geometry_mesh(item.geometry, chain.path, package_dirs, files_read)
                if mesh is None:
                    continue
                origin = np.eye(4) if item.origin is None else _in_mm(item.origin)
                if not np.isfinite(origin).all():
                    raise ConfigError(f"{chain.path}: link {link.name!r}: the origin of one of its {kind} is not "
                                      f"finite (xyz and rpy must be numbers)")
                mesh.apply_transform(rigid_inverse(frames0[k]) @ chain.link_pose[link.name] @ origin @ scale)
                pieces[k].append(mesh)
        if kind == "visuals":
            visual_pieces = pieces
        elif any(pieces[1:]):  # per link, not per robot: one without collision geometry keeps its visual
            pieces[1:] = [p or [m.copy() for m in v] for p, v in zip(pieces[1:], visual_pieces[1:])]
        links = pieces[1:]
        out.append((tuple((trimesh.util.concatenate(p), np.eye(4)) if p else ("", np.eye(4)) for p in links)
                    if any(links) else (),
                    (trimesh.util.concatenate(pieces[0]), np.eye(4)) if pieces[0] else ()))
    return out[0], out[1]
