"""Workpieces: meshes loaded through trimesh, or built-in analytic shapes with exact truth.

One loader serves the Blender panel and the headless pipeline. A workpiece is a
mesh in the table (workpiece) frame in millimetres, plus its ground truth: the
analytic shape where there is one (exact distances), else the mesh itself.

Units: STL, OBJ and PLY carry no units and are read as millimetres; glTF/GLB
are metres by their specification and are scaled by 1000. ``scale`` overrides both.
"""

from __future__ import annotations

import re
import warnings
import weakref
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import trimesh

from ..errors import InputError
from .ply_polygons import read_polygon_ply
from .polygons import needs_own_obj_reader, read_obj, triangulate
from .shapes import Cylinder, PlanePatch, Sphere, StepBlock
from ..kinematics.transforms import check_transform, rot_z, trans

FORMATS = (".stl", ".obj", ".ply", ".glb", ".gltf")
GLTF_FORMATS = (".glb", ".gltf")  # metres and +Y up, by the glTF specification
# glTF's +Y up turned to the table's +Z up, as Blender imports it: (x, y, z) -> (x, -z, y).
GLTF_TO_Z_UP = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
MAX_EXTENT_MM = 5000.0   # a workpiece on a rotary table; larger is a unit mistake
MIN_EXTENT_MM = 0.01
# A mesh file's part: smaller than 5 mm (four widths of the default probe's laser line) or
# larger than a metre on a 300 mm table is a file in another unit far more often than a real
# part: Blender's own STL export of a 2 m model writes 2 (metres), read as 2 mm here.
FILE_MIN_EXTENT_MM = 5.0
FILE_MAX_EXTENT_MM = 1000.0
MAX_FACES = 10_000_000

BUILTINS = {
    # name: (constructor, default parameters); each stands on the table (z = 0 up).
    "plane": (lambda pose, **kw: PlanePatch(pose, **kw), dict(width_mm=120.0, height_mm=120.0)),
    "sphere": (lambda pose, **kw: Sphere(pose @ trans(0, 0, kw["radius_mm"]), **kw), dict(radius_mm=30.0)),
    "cylinder": (lambda pose, **kw: Cylinder(pose, **kw), dict(radius_mm=25.0, height_mm=60.0)),
    "step_block": (lambda pose, **kw: StepBlock(pose, **kw), dict(heights_mm=(45.0, 30.0, 15.0), step_mm=25.0,
                                                                    width_mm=50.0)),
}


@dataclass(frozen=True, eq=False)
class Workpiece:
    """mesh: (trimesh) in the table frame, mm; truth: analytic shape or the mesh; source: file or builtin name."""

    name: str
    mesh: trimesh.Trimesh
    truth: object
    source: str
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))
    notes: tuple = ()  # what loading it changed, for the scan's warnings (a mesh turned right side out)

    @property
    def is_analytic(self) -> bool:
        return self.truth is not self.mesh


def turned_on_table(wp: Workpiece, deg: float) -> Workpiece:
    """``wp`` turned by ``deg`` degrees about the table's axis, its exact truth with it: the
    same part put down at another angle."""
    if isinstance(deg, bool) or not isinstance(deg, (int, float, np.integer, np.floating)) or not np.isfinite(deg):
        raise InputError(f"a workpiece's turn must be a finite number of degrees, got {deg!r}")
    R = rot_z(np.radians(float(deg)))
    mesh = wp.mesh.copy()
    mesh.apply_transform(R)
    truth = replace(wp.truth, pose=R @ wp.truth.pose) if wp.is_analytic else mesh
    return Workpiece(wp.name, mesh, truth, wp.source, R @ wp.pose, wp.notes)


def builtin_workpiece(kind: str, pose=None, **params) -> Workpiece:
    """A built-in analytic shape placed by ``pose`` (shape -> table frame) with exact truth."""
    if kind not in BUILTINS:
        raise InputError(f"unknown built-in workpiece {kind!r}; choose one of: {', '.join(BUILTINS)}")
    pose = np.eye(4) if pose is None else check_transform(pose, f"{kind} pose")
    make, defaults = BUILTINS[kind]
    unknown = set(params) - set(defaults)
    if unknown:
        raise InputError(f"{kind}: unknown parameter(s) {', '.join(sorted(unknown))}; allowed: {', '.join(defaults)}")
    for key, value in params.items():  # a size far under the smallest part made NaN vertices (and numpy's warnings)
        for v in (value if isinstance(value, (tuple, list)) else (value,)):
            if isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) \
                    and 0 < v < MIN_EXTENT_MM / 2:
                raise InputError(f"{kind} {key} {v:g} mm is too small: a part is at least {MIN_EXTENT_MM:g} mm across; "
                                 f"give sizes from {MIN_EXTENT_MM / 2:g} mm")
    shape = make(pose, **{**defaults, **params})
    mesh = shape.mesh()
    check_mesh(mesh, f"the built-in {kind}", f"give it a size from {MIN_EXTENT_MM:g} to {MAX_EXTENT_MM:g} mm "
                                             f"across with its size keys ({', '.join(defaults)})")
    return Workpiece(kind, mesh, shape, f"builtin:{kind}", pose, _facet_notes(kind, mesh, shape))


def _facet_notes(kind: str, mesh: trimesh.Trimesh, shape) -> tuple:
    """A warning where the drawn mesh's flat facets lie deeper inside the exact shape than
    shapes.FACET_SAG_MM (a sphere of half a metre: 36 µm, which the scan's error carried as
    the scanner's): their deepest points are their middles and the middles of their edges,
    measured only where the shape's own bound allows more (a load of the demo's sphere took
    75 ms for it)."""
    from .shapes import FACET_SAG_MM

    if shape.facet_sag_bound_mm() <= FACET_SAG_MM:
        return ()
    edges = mesh.vertices[mesh.edges_unique].mean(axis=1)
    sag = -float(np.min(shape.signed_distance(np.vstack([mesh.triangles_center, edges]))))
    if sag <= FACET_SAG_MM * 1.05:
        return ()
    return (f"the built-in {kind} is drawn with flat facets that lie up to {sag * 1e3:.1f} um inside the exact shape "
            f"its error is measured against: that much of the error (a bias) is the drawing's, not the scanner's "
            f"(a part of this size as a mesh file is measured against itself)",)


def check_mesh(mesh: trimesh.Trimesh, what: str, fix: str = "is it in another unit? Set the workpiece's scale key"
               ) -> trimesh.Trimesh:
    """Refuse meshes that cannot be a workpiece, naming what is wrong; ``fix``: what to do
    about a size out of range (a file's unit; a built-in shape's own size keys)."""
    if len(mesh.vertices) == 0 or len(mesh.faces) == 0:
        raise InputError(f"{what}: the mesh is empty (no faces); a workpiece needs a surface")
    if not np.all(np.isfinite(mesh.vertices)):
        raise InputError(f"{what}: the mesh has NaN or infinite vertex coordinates")
    if len(mesh.faces) > MAX_FACES:
        raise InputError(f"{what}: {len(mesh.faces)} faces is more than the {MAX_FACES} allowed; decimate it first")
    extent = float(np.max(mesh.extents))
    if extent > MAX_EXTENT_MM:
        raise InputError(f"{what}: the mesh is {extent:g} mm across, larger than {MAX_EXTENT_MM:g} mm: {fix}")
    if extent < MIN_EXTENT_MM:
        raise InputError(f"{what}: the mesh is only {extent:g} mm across (at least {MIN_EXTENT_MM:g} mm): {fix}")
    if not float(mesh.area) > MIN_EXTENT_MM ** 2:  # every face a line or a point: nothing to light
        raise InputError(f"{what}: the mesh has no surface ({float(mesh.area):.3g} mm² in all: its faces' corners lie on "
                         f"lines); a workpiece needs a surface of at least {MIN_EXTENT_MM ** 2:g} mm²")
    return mesh


def _text_has_non_finite(path: Path, limit: int = 64 << 20) -> bool:
    """Whether a text mesh file (OBJ, ASCII STL or PLY) of at most ``limit`` bytes writes a
    NaN or an infinity as a number."""
    if path.stat().st_size > limit:
        return False
    try:
        text = path.read_text(encoding="ascii", errors="strict")
    except (OSError, UnicodeDecodeError):  # binary: its reader's words stand
        return False
    return re.search(r"(?<![\w.])[-+]?(nan|inf(inity)?)(\.\d*)?(?![\w.])", text, re.IGNORECASE) is not None


def _obj_zero_index_line(path: Path, limit: int = 64 << 20) -> int | None:
    """The first line of an OBJ file (at most ``limit`` bytes) whose face names vertex 0, which
    OBJ does not have (None where none does)."""
    if path.stat().st_size > limit:
        return None
    try:
        with path.open("r", encoding="utf-8", errors="replace") as fh:
            for number, line in enumerate(fh, 1):
                if line.startswith("f ") and any(t.split("/")[0] in ("0", "-0") for t in line.split()[1:]):
                    return number
    except OSError:
        return None
    return None


def _point_count(path: Path) -> int:
    """How many points a file that holds no faces holds (a scan's point cloud), 0 where it is
    not one."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            loaded = trimesh.load(path, process=False)
    except Exception:  # what cannot be read is said by the caller
        return 0
    return len(loaded.vertices) if isinstance(loaded, trimesh.PointCloud) else 0


def _content_format(path: Path) -> str | None:
    """The mesh format a file's first bytes show (".ply", ".glb", ".gltf", ".obj", ".stl"), None
    where they show none: asked only when a file could not be read as its extension says, to
    name what it is instead (a PLY saved as .stl read as "not a readable STL")."""
    with open(path, "rb") as fh:
        head = fh.read(4096)
    size = path.stat().st_size
    if head.startswith(b"ply"):
        return ".ply"
    if head.startswith(b"glTF"):
        return ".glb"
    text = head.lstrip()
    if text.startswith(b"{") and b'"asset"' in head:
        return ".gltf"
    if text.lower().startswith(b"solid") and b"facet" in head.lower():
        return ".stl"
    if len(head) >= 84 and size == 84 + 50 * int.from_bytes(head[80:84], "little"):
        return ".stl"
    lines = [ln.strip() for ln in head.splitlines()]
    if any(ln.startswith(b"v ") for ln in lines) and any(ln.startswith((b"f ", b"o ", b"g ", b"vn ")) for ln in lines):
        return ".obj"
    return None


def _misnamed(path: Path) -> str | None:
    """One line for a file whose content is another mesh format than its extension names."""
    actual = _content_format(path)
    if actual is None or actual == path.suffix.lower():
        return None
    name = actual[1:].upper()
    article = "an" if name[0] in "AEFHILMNORSX" else "a"  # as the letters are said: an STL, an OBJ, a PLY
    return (f"{path}: it holds {article} {name} mesh, but is named {path.suffix}; a mesh is read "
            f"by its extension: rename it to {path.stem}{actual}")


def _without_collapsed_faces(mesh: trimesh.Trimesh, path: Path) -> trimesh.Trimesh:
    """The mesh without faces that name a corner twice (CAD exports leave them; three of them
    made a closed flange read as open, its bias dropped); refused where most faces repeat
    others, which a well-read file never has (an OBJ of relative, negative indices, read as
    768 copies of one triangle, was scanned as a 0.03 mm sliver)."""
    F = np.asarray(mesh.faces)
    collapsed = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 0] == F[:, 2])
    if collapsed.all():
        raise InputError(f"{path}: every face names one corner twice: no surface could be read")
    if collapsed.any():
        mesh = trimesh.Trimesh(mesh.vertices, F[~collapsed], process=False)
        mesh.remove_unreferenced_vertices()
    _, first = np.unique(np.sort(np.asarray(mesh.faces), axis=1), axis=0, return_index=True)
    distinct = len(first)
    if distinct < 0.5 * len(mesh.faces):
        raise InputError(f"{path}: {len(mesh.faces) - distinct} of its {len(mesh.faces)} faces repeat others: the "
                         f"file was not read as written (an OBJ's relative, negative indices are one cause); "
                         f"export it again with plain indices, or as STL or PLY")
    if distinct < len(mesh.faces):
        # A face saved twice (a double-sided export saves each once per winding): each copy is
        # the nearest face to half the points on it, and a point matched to the copy facing
        # the other way would not count as on the same surface (coverage); a closed part with
        # one repeated face reads as open (no bias). Each is kept once.
        mesh = trimesh.Trimesh(mesh.vertices, np.asarray(mesh.faces)[np.sort(first)], process=False)
    return mesh


def _body_labels(mesh: trimesh.Trimesh) -> np.ndarray:
    """Each face's closed body (its connected piece), numbered from 0."""
    vertex_piece = trimesh.graph.connected_component_labels(mesh.edges, node_count=len(mesh.vertices))
    return np.unique(vertex_piece, return_inverse=True)[1][mesh.faces[:, 0]]


def _body_volumes(mesh: trimesh.Trimesh, labels: np.ndarray) -> np.ndarray:
    """Each closed body's signed volume (mm³; negative: wound inward), from its faces' tetrahedra
    to the origin."""
    tri = mesh.vertices[mesh.faces]
    six = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))
    return np.bincount(labels, weights=six, minlength=int(labels.max()) + 1) / 6.0


def _bodies_wound_inward(mesh: trimesh.Trimesh, labels: np.ndarray) -> list[int]:
    """The bodies of a closed, consistently wound mesh that are wound inside out. A body lying
    wholly inside an odd number of the others is a sealed void's wall and rightly faces the
    void (negative volume; turned out, the void read as solid). So a body of negative volume
    is inside out unless it lies so; one of positive volume is, where it lies wholly inside a
    body that is itself inside out (a file saved inside out throughout: the void's wall then
    faces out); otherwise it is a solid within a solid (_overlap_note)."""
    count = int(labels.max()) + 1
    volumes = _body_volumes(mesh, labels)
    if count == 1 or count > MAX_OVERLAP_BODIES:
        return [k for k in range(count) if volumes[k] < 0]
    bodies = [trimesh.Trimesh(mesh.vertices, mesh.faces[labels == k], process=False) for k in range(count)]
    inside = {}  # body: the bodies it lies wholly inside
    for k, body in enumerate(bodies):
        corners = body.vertices[np.unique(body.faces)]
        corners = corners[:: max(1, len(corners) // 64)]
        inside[k] = [j for j, other in enumerate(bodies)
                     if j != k and abs(volumes[j]) > abs(volumes[k])
                     and np.all((other.bounds[0] <= corners) & (corners <= other.bounds[1]))
                     and bool(np.all(other.contains(corners)))]
    wrong = {k for k in range(count) if volumes[k] < 0 and len(inside[k]) % 2 == 0}
    for k in range(count):
        if volumes[k] > 0 and len(inside[k]) % 2 == 1:
            container = min(inside[k], key=lambda j: abs(volumes[j]))  # the body it sits in directly
            if container in wrong:
                wrong.add(k)
    return sorted(wrong)


def _overlap_note(mesh: trimesh.Trimesh, labels: np.ndarray, path: Path, role: str) -> str | None:
    """A note where the mesh's closed bodies (``labels``: each face's) reach into each other,
    saved together without a union: the surface inside another body can never be seen, yet
    counts in the part's whole coverage. Its share is estimated from OVERLAP_SAMPLES points
    spread over the surface; up to MAX_OVERLAP_BODIES bodies are looked at."""
    count = int(labels.max()) + 1
    if not 2 <= count <= MAX_OVERLAP_BODIES:
        return None
    bodies = [trimesh.Trimesh(mesh.vertices, mesh.faces[labels == k]) for k in range(count)]
    if not all(b.is_watertight for b in bodies):
        return None
    solid = [b.volume > 0 for b in bodies]  # the others are sealed voids' walls (see _void_note)
    hidden = 0.0
    for i, a in enumerate(bodies):
        if not solid[i]:
            continue
        others = [b for j, b in enumerate(bodies) if j != i and solid[j] and np.all(
            np.maximum(a.bounds[0], b.bounds[0]) < np.minimum(a.bounds[1], b.bounds[1]))]
        if not others:
            continue
        points = trimesh.sample.sample_surface(a, max(200, int(OVERLAP_SAMPLES * a.area / mesh.area)), seed=i)[0]
        inside = np.zeros(len(points), bool)
        for b in others:
            inside |= b.contains(points)
        hidden += a.area * inside.mean()
    if hidden < 1e-3 * mesh.area:
        return None
    return (f"the {role} mesh {path.name} holds {count} closed bodies that reach into each other: about "
            f"{hidden / mesh.area * 100:.2g} % of its surface lies inside another body, where no laser reaches, and "
            f"still counts in the whole part's coverage; unite them first (a boolean union) to scan the part as one "
            f"solid")


def _void_note(mesh: trimesh.Trimesh, labels: np.ndarray, path: Path, role: str) -> str | None:
    """A note where a closed, consistently wound mesh holds sealed voids (bodies wound to face
    inward, inside another): their walls are the part's surface, but no laser reaches them."""
    if not (mesh.is_watertight and mesh.is_winding_consistent) or labels.max() < 1:
        return None
    voids = np.flatnonzero(_body_volumes(mesh, labels) < 0)
    if not len(voids):
        return None
    share = float(mesh.area_faces[np.isin(labels, voids)].sum()) / mesh.area
    return (f"the {role} mesh {path.name} holds {len(voids)} sealed void{'s' if len(voids) > 1 else ''} "
            f"({share * 100:.2g} % of its surface), which no laser reaches: the void walls count in the whole "
            f"part's coverage, not in the measurable surface's")


def _gaps_to(points: np.ndarray, body: trimesh.Trimesh, corners: np.ndarray) -> np.ndarray:
    """(n,) mm: each point's distance to ``body``'s faces where it is within LOOSE_GAP_MM, else a
    bound beyond it. Exact distances are asked only near the points: a point farther than the
    longest edge plus the gap from every corner of the body is farther than the gap from its
    faces (a million-face scan with specks around it took seconds to build a tree over it all).
    ``corners``: the body's vertices that its faces use."""
    from scipy.spatial import cKDTree

    from .metrics import unsigned_distances

    tri = body.vertices[body.faces]
    longest = float(np.sqrt(max(np.max(np.sum((tri - np.roll(tri, 1, axis=1)) ** 2, axis=2)), 0.0)))
    tree = cKDTree(body.vertices[corners])
    reach = LOOSE_GAP_MM + longest
    gap, _ = tree.query(points, distance_upper_bound=reach)  # inf beyond the reach
    maybe = np.isfinite(gap)
    gap[maybe] = np.inf
    if maybe.any():
        near = np.unique(np.concatenate(tree.query_ball_point(points[maybe], reach)).astype(np.int64))
        faces = body.faces[np.isin(body.faces, corners[near]).any(axis=1)]
        gap[maybe] = unsigned_distances(points[maybe], trimesh.Trimesh(body.vertices, faces, process=False))
    return gap


def _loose_pieces_note(mesh: trimesh.Trimesh, labels: np.ndarray, path: Path, role: str) -> str | None:
    """A note where the mesh holds pieces apart from its main body (LOOSE_GAP_MM away at least),
    each under LOOSE_AREA_SHARE of its area: a scanned mesh's debris, specks floating beside or
    under the part, which are scanned and measured as part of the part and, lying lowest,
    decide where it rests. Faces hanging on the body by a corner or a hair's gap are not loose."""
    area = np.bincount(labels, weights=mesh.area_faces)
    small = np.flatnonzero(area < LOOSE_AREA_SHARE * area.max())
    if len(small) == 0:
        return None
    in_small = np.isin(labels, small)
    body = trimesh.Trimesh(mesh.vertices, mesh.faces[~in_small], process=False)
    corners = np.unique(mesh.faces[in_small])
    body_corners = np.unique(body.faces)
    gap = _gaps_to(mesh.vertices[corners], body, body_corners)
    vertex_piece = np.zeros(len(mesh.vertices), dtype=np.int64)
    vertex_piece[mesh.faces] = labels[:, None]
    nearest = np.full(len(area), np.inf)
    np.minimum.at(nearest, vertex_piece[corners], gap)
    small = small[nearest[small] > LOOSE_GAP_MM]
    if len(small) and mesh.is_watertight:  # (every piece closed, the body too; asked of the body alone, seconds)
        # A piece inside the closed body is not debris beside it: the overlap note speaks of that.
        first_face = np.unique(labels, return_index=True)[1]  # each piece's first face
        small = small[~body.contains(mesh.vertices[mesh.faces[first_face[small], 0]])]
    if len(small) == 0:
        return None
    loose = np.isin(labels, small)
    body_low = float(body.vertices[body_corners][:, 2].min())
    low = float(mesh.vertices[np.unique(mesh.faces[loose])][:, 2].min())
    piece_lo = np.full((len(area), 3), np.inf)
    piece_hi = np.full((len(area), 3), -np.inf)
    used = np.unique(mesh.faces[loose])
    np.minimum.at(piece_lo, vertex_piece[used], mesh.vertices[used])
    np.maximum.at(piece_hi, vertex_piece[used], mesh.vertices[used])
    widest = float((piece_hi[small] - piece_lo[small]).max())
    one = len(small) == 1
    text = (f"the {role} mesh {path.name} holds {'a loose piece' if one else f'{len(small)} loose pieces'} apart "
            f"from its body, {'' if one else 'each '}under {LOOSE_AREA_SHARE * 100:g} % of its area "
            f"({'' if one else 'up to '}{widest:.2g} mm across)")
    below = body_low - low
    if below > SINK_TOLERANCE_MM:
        text += f", {'' if one else 'the lowest '}{below:.2g} mm below the rest, {RESTS_ON_LOOSE}"
    it, are = ("it", "is") if one else ("they", "are")
    return (text + f"; {it} {are} scanned and measured as part of the part: a scan's debris? Delete "
            f"{it if one else 'them'} from the mesh if {it} {are} not the part's")


def _gltf_json(path: Path) -> dict | None:
    """A glTF's JSON (a .gltf file, or a GLB's first chunk); None where it cannot be read (the
    mesh reader then says what is wrong)."""
    import json
    import struct

    try:
        with open(path, "rb") as f:
            head = f.read(20)
            if head[:4] == b"glTF" and len(head) == 20 and head[16:20] == b"JSON":
                return json.loads(f.read(struct.unpack("<I", head[12:16])[0]))
            if path.suffix.lower() == ".gltf":
                return json.loads(head + f.read())
    except (OSError, ValueError, UnicodeDecodeError, struct.error):
        pass
    return None


COMPRESSIONS = ("KHR_draco_mesh_compression", "EXT_meshopt_compression")


def _check_gltf_encoding(path: Path) -> None:
    """Refuse a glTF whose vertices the reader would read wrong, naming the export option: a
    compressed one (Draco, meshopt: refused as "every face names one corner twice"), or one
    whose positions are normalized integers (KHR_mesh_quantization: read as 1.3 km across)."""
    doc = _gltf_json(path)
    if not isinstance(doc, dict):
        return
    required = set(doc.get("extensionsRequired") or [])  # (merely used: the file keeps plain data beside it)
    squeezed = [e for e in COMPRESSIONS if e in required]
    if squeezed:
        raise InputError(f"{path}: its meshes are compressed ({squeezed[0]}), which this reader cannot decode: "
                         f"export it again without compression (in Blender's glTF exporter, leave Compression off)")
    accessors = doc.get("accessors") or []
    for mesh in doc.get("meshes") or []:
        for prim in (mesh.get("primitives") or []) if isinstance(mesh, dict) else []:
            at = (prim.get("attributes") or {}).get("POSITION") if isinstance(prim, dict) else None
            if isinstance(at, int) and 0 <= at < len(accessors) and isinstance(accessors[at], dict) \
                    and accessors[at].get("normalized"):
                raise InputError(f"{path}: its vertex positions are quantized to normalized integers "
                                 f"(KHR_mesh_quantization), which this reader cannot scale back: export it again "
                                 f"with float positions")


def _check_stl_header(path: Path) -> None:
    """A binary STL announces its triangles in its header: a file large enough to hold more than
    MAX_FACES of them that announces more is refused before it is read (a 2 GB file took 15 s
    to be found unreadable). Anything else is left to the reader (a small file with a wild
    count is not an STL at all, and the reader says so)."""
    if path.suffix.lower() != ".stl":
        return
    size = path.stat().st_size
    with open(path, "rb") as fh:
        head = fh.read(84)
    count = int.from_bytes(head[80:84], "little") if len(head) == 84 else 0
    # Binary (an ASCII STL starts with "solid"), a plausible count, and less than it needs: cut
    # short (the reader said only that no triangles could be read).
    if not head.lstrip().lower().startswith(b"solid") and 0 < count <= MAX_FACES and 84 <= size < 84 + 50 * count:
        raise InputError(f"{path}: the binary STL announces {count} triangles, and its {size} bytes hold only "
                         f"{(size - 84) // 50}: the file is cut short; export it again")
    if size < 84 + 50 * MAX_FACES:
        return
    if count > MAX_FACES and (size == 84 + 50 * count or not head.lstrip().lower().startswith(b"solid")):
        raise InputError(f"{path}: the binary STL announces {count} triangles, more than the {MAX_FACES} allowed; "
                         f"decimate it first")


def load_workpiece(path: str | Path, pose=None, scale: float | None = None, role: str = "part") -> Workpiece:
    """A mesh file (STL/OBJ/PLY/GLB/glTF) placed by ``pose`` in the table frame; its truth is the
    mesh. ``role``: what the mesh is, for the messages (the part, a fixture)."""
    path = Path(path)
    if path.suffix.lower() not in FORMATS:
        raise InputError(f"{path}: unsupported mesh format {path.suffix or '(none)'}; use one of {', '.join(FORMATS)}")
    if path.is_dir():
        raise InputError(f"{path}: is a folder, not a mesh file")
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    if path.stat().st_size == 0:
        raise InputError(f"{path}: the file is empty (0 bytes); was it written to the end?")
    _check_stl_header(path)
    if path.suffix.lower() in GLTF_FORMATS:
        _check_gltf_encoding(path)
    try:
        # Unprocessed first: processing drops the faces of NaN vertices without a word. A broken
        # file's arithmetic (normals of infinite vertices) warns; what is wrong is said below.
        # Polygons split in their own plane (see polygons.py): an OBJ or a PLY with n-gons.
        own = None
        if path.suffix.lower() == ".obj" and needs_own_obj_reader(path):
            own = read_obj(path)
        elif path.suffix.lower() == ".ply" and not _misnamed(path):
            own = read_polygon_ply(path)
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            if own is not None:
                mesh = trimesh.Trimesh(own[0], triangulate(*own), process=False)
            else:
                mesh = trimesh.load(path, force="mesh", process=False)
    except InputError:
        raise
    except Exception as exc:  # trimesh raises many kinds for broken files
        if _text_has_non_finite(path):  # a text reader stops at "nan" with words of its own
            raise InputError(f"{path}: its coordinates include NaN or infinite values; a workpiece needs finite "
                             f"ones") from None
        # A binary PLY mixing polygon sizes (Blender's exporter's default), which trimesh cannot read.
        raise InputError(_misnamed(path) or f"{path}: cannot read the mesh ({type(exc).__name__}: {exc})") from None
    zero = _obj_zero_index_line(path) if path.suffix.lower() == ".obj" else None
    if zero:  # the reader drops such a face without a word
        raise InputError(f"{path}: line {zero} names vertex 0, and an OBJ counts its vertices from 1 (or from -1 "
                         f"back); export it again")
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        points = _point_count(path)
        if points:
            raise InputError(f"{path}: {points} points and no faces: a point cloud, not a surface; mesh it first "
                             f"(a surface reconstruction), then give the mesh")
        raise InputError(_misnamed(path) or f"{path}: no triangles could be read from it: not a readable "
                         f"{path.suffix[1:].upper()} mesh (or one with no faces)")
    if not np.all(np.isfinite(mesh.vertices)):
        bad = int(np.sum(~np.isfinite(mesh.vertices).all(axis=1)))
        raise InputError(f"{path}: {bad} {'vertex has' if bad == 1 else 'vertices have'} NaN or infinite "
                         f"coordinates; a workpiece needs finite ones")
    faces = np.asarray(mesh.faces)
    if faces.size and (faces.min() < 0 or faces.max() >= len(mesh.vertices)):  # (an IndexError's traceback)
        bad = int(np.sum((faces < 0).any(axis=1) | (faces >= len(mesh.vertices)).any(axis=1)))
        raise InputError(f"{path}: {bad} of its {len(faces)} faces name corners beyond its {len(mesh.vertices)} "
                         f"vertices: the file is damaged; export it again")
    with np.errstate(all="ignore"), warnings.catch_warnings():  # huge coordinates: said below, not as warnings
        warnings.simplefilter("ignore", RuntimeWarning)
        mesh = trimesh.Trimesh(mesh.vertices, mesh.faces, process=True)
    mesh = _without_collapsed_faces(mesh, path)
    if path.suffix.lower() in GLTF_FORMATS:
        mesh.apply_transform(GLTF_TO_Z_UP)
    guessed = scale is None  # the file's unit taken from its format: a size out of the usual range is doubted
    if guessed:
        scale = 1000.0 if path.suffix.lower() in GLTF_FORMATS else 1.0
    if not np.isfinite(scale) or scale <= 0:
        raise InputError(f"{path}: scale must be a positive number, got {scale}")
    if scale != 1.0:
        finite = np.isfinite(mesh.vertices).all()
        with np.errstate(over="ignore", invalid="ignore"):  # an overflow is named below, not warned of
            mesh.apply_scale(scale)
        if finite and not np.isfinite(mesh.vertices).all():  # the file's coordinates were fine
            raise InputError(f"{path}: scale {scale:g} makes the mesh's coordinates overflow: give the factor from the "
                             f"file's unit to mm (e.g. 1000 for metres, 25.4 for inches)")
    # A file's own, narrower size range first, so every part of the wrong size gets one message;
    # a scale given outright says the size is meant, within the wider range of any workpiece.
    extent = float(np.max(mesh.extents))
    if guessed and not FILE_MIN_EXTENT_MM <= extent <= FILE_MAX_EXTENT_MM:
        key = "the workpiece's" if role == "part" else f"the {role}'s"
        unit = "metres" if scale == 1000 else "mm"
        # (a glTF is read as metres already: its other unit is mm, scale = 1, which went unsaid)
        examples = ("scale = 1 for millimetres, 25.4 for inches" if scale == 1000
                    else "scale = 1000 for metres, 25.4 for inches")
        raise InputError(f"{path}: the {role} is {extent:.4g} mm across (read as {unit}); "
                         f"{role}s in a cell are usually {FILE_MIN_EXTENT_MM:g} to {FILE_MAX_EXTENT_MM:g} mm: is the "
                         f"file in another unit? Set {key} scale key (e.g. {examples}; "
                         f"scale = {scale:g} where it really is {extent:.4g} mm"
                         f"{PART_SCALE_HINT if role == 'part' else ''})")
    check_mesh(mesh, str(path), fix=f"is scale {scale:g} right?")
    notes = ()
    if mesh.is_watertight and not mesh.is_winding_consistent:
        # Closed, but some faces wound against their neighbours (an export's flipped patch): its
        # surface is not in doubt, so each face is turned to agree with its neighbours (and the
        # whole turned outward below), rather than the part read as open with no bias.
        fixed = mesh.copy()
        trimesh.repair.fix_winding(fixed)
        fixed = trimesh.Trimesh(fixed.vertices, fixed.faces, process=False)  # normals from the new winding
        if fixed.is_winding_consistent:
            as_read, mesh = mesh.face_normals.copy(), fixed
    elif not mesh.is_winding_consistent and len(mesh.faces) <= MAX_REWOUND_OPEN_FACES:
        # Open, with faces wound against their neighbours: it rendered and measured apart from
        # the same surface wound alike (a hunt: RMS 12.1 against 9.9 µm, a point beyond 0.2 mm).
        # An open surface has no outside to turn to: each piece keeps the side most of its area
        # faced as written.
        as_read, fixed = mesh.face_normals.copy(), mesh.copy()
        trimesh.repair.fix_winding(fixed)
        fixed = trimesh.Trimesh(fixed.vertices, fixed.faces, process=False)
        if fixed.is_winding_consistent:
            labels = _body_labels(fixed)
            agree = np.einsum("ij,ij->i", fixed.face_normals, as_read) * fixed.area_faces
            against = np.bincount(labels, weights=agree, minlength=int(labels.max()) + 1) < 0
            faces = np.array(fixed.faces)
            flip = against[labels]
            faces[flip] = np.fliplr(faces[flip])
            mesh = trimesh.Trimesh(fixed.vertices, faces, process=False)
            turned = int(np.sum(np.einsum("ij,ij->i", mesh.face_normals, as_read) < 0))
            notes = (f"{turned} of the {len(mesh.faces)} faces of the open {role} mesh {path.name} were wound "
                     f"against their neighbours; they were turned to agree with the most of the surface around "
                     f"them",)
        as_read = None
    else:
        as_read = None
    if mesh.is_watertight and mesh.is_winding_consistent:
        # A body wound inward: the signed distance would call its outside its inside, and the
        # bias would change sign. The surface is the same; its outside is not in doubt. Each
        # separate body is judged on its own (one may be right, another inside out).
        labels = _body_labels(mesh)
        wrong = _bodies_wound_inward(mesh, labels)
        inverted = len(wrong)
        if inverted:
            # Rebuilt, not mesh.invert(): that keeps the cached face normals, which then point
            # inward against the new winding (the renderers saw every face from behind, and no
            # point landed on the part).
            faces = np.array(mesh.faces)
            flip = np.isin(labels, wrong)
            faces[flip] = np.fliplr(faces[flip])
            mesh = trimesh.Trimesh(mesh.vertices, faces, process=False)
            count = int(labels.max()) + 1
            which = "" if count == 1 else f" ({inverted} of its {count} bodies)"
            notes = (f"the {role} mesh {path.name} was wound inside out{which}, its faces facing inward; it was "
                     "turned right side out, so that inside and outside, and the bias's sign, are the part's",)
    if as_read is not None and mesh.is_winding_consistent:  # one note for the whole repair, counted as read
        turned = int(np.sum(np.einsum("ij,ij->i", mesh.face_normals, as_read) < 0))
        notes = (f"{turned} of the {len(mesh.faces)} faces of the {role} mesh {path.name} were wound against the "
                 f"rest; they were turned, so that the part is one closed surface facing out, with an inside and a "
                 f"bias",)
    pose = np.eye(4) if pose is None else check_transform(pose, f"{path.name} pose")
    mesh.apply_transform(pose)  # before the notes: which piece lies lowest is the posed part's
    labels = _body_labels(mesh)
    notes = notes + tuple(n for n in (_loose_pieces_note(mesh, labels, path, role),
                                      _overlap_note(mesh, labels, path, role),
                                      _void_note(mesh, labels, path, role)) if n)
    return Workpiece(path.stem, mesh, mesh, str(path), pose, notes)


PART_SCALE_HINT = ("; in the panel, its Scale field; in a script, resting_on_table(load_workpiece(path, scale=...))[0], "
                   "which puts it on the table as Scanner(workpiece=path) does")
LOOSE_AREA_SHARE = 0.01  # a piece apart from the mesh's body, under this share of its area, is noted as loose
LOOSE_GAP_MM = 0.1       # ... where it lies this far from the body at least
MAX_OVERLAP_BODIES = 50  # closed bodies looked at for reaching into each other
MAX_REWOUND_OPEN_FACES = 2_000_000  # an open mesh wound unevenly is made even up to this size
OVERLAP_SAMPLES = 20000  # points spread over the surface to estimate the share inside another body
RESTS_ON_LOOSE = "so the part rests on it"  # the loose note's words where a loose piece lies lowest
SINK_TOLERANCE_MM = 0.05  # a part may reach this far below the table top (a mesh's rounding)
TABLE_TOP_FACE_MM = 1e-3  # a face whose corners all lie this near z = 0 lies in the table top


def in_table_top(mesh: trimesh.Trimesh) -> np.ndarray:
    """Which faces (bool per face) lie in the table top (z = 0 in the table frame): every
    corner within TABLE_TOP_FACE_MM of it."""
    return np.all(np.abs(mesh.vertices[mesh.faces][:, :, 2]) <= TABLE_TOP_FACE_MM, axis=1)


def drawn_mesh(wp: Workpiece) -> trimesh.Trimesh | None:
    """The part as the renderers draw it and the laser meets it: an open mesh without its faces
    that lie in the table top (None where that is all of it: a sheet lying flat). Those
    coincide with the table, which is drawn; drawn too, each ray would meet either surface,
    their normals opposite, and the line's light alternates between them (the built-in plane
    lying on the table read 141 µm RMS, 0.3 mm at worst; 1.8 µm lifted 0.5 mm). What is there
    to measure is the table, and the part's truth there is the same plane. A closed part's own
    faces on the table top face down, hidden under it either way, and stay. The truth and
    every error and coverage against it keep the whole mesh. Worked out once per part (the
    renderers, the laser's casts and the warnings all ask)."""
    if wp in _DRAWN:
        return _DRAWN[wp]
    mesh, out = wp.mesh, wp.mesh
    if not mesh.is_watertight:
        flat = in_table_top(mesh)
        if flat.all():
            out = None
        elif flat.any():
            out = mesh.copy()
            out.update_faces(~flat)
            out.remove_unreferenced_vertices()
    _DRAWN[wp] = out
    return out


_DRAWN: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()  # workpiece -> drawn_mesh's answer


def depth_below_table(wp: Workpiece) -> float:
    """How far (mm) the part reaches below the table top (z = 0 in the table frame); 0 where it
    does not."""
    return max(0.0, -float(wp.mesh.bounds[0][2]))


def resting_on_table(wp: Workpiece) -> tuple[Workpiece, float]:
    """A mesh-file part given no pose (the panel's, ``Scanner(workpiece=path)``) moved straight
    up or down so that its lowest point lies on the table top, as a part is put on a table:
    (the part, the lift in mm, negative where it came down). Its truth moves with it. Its x and
    y stay the file's, so one lying wholly beyond the table's rim is refused (check_over_table)."""
    check_over_table(wp, "its x and y are the file's, with the table's axis at x = y = 0: centre the part in the "
                         "file, or place it with a scan config's [workpiece.pose]")
    lift = -float(wp.mesh.bounds[0][2])
    if wp.is_analytic or lift == 0.0:
        return wp, 0.0
    T = np.eye(4)
    T[2, 3] = lift
    mesh = wp.mesh.copy()
    mesh.apply_transform(T)
    return Workpiece(wp.name, mesh, mesh, wp.source, T @ wp.pose, wp.notes), lift


def lift_text(lift_mm: float, decimals: int = 1) -> str | None:
    """What :func:`resting_on_table` did, in words ("lifted 10.0 mm so that ..."); None where
    it moved the part by less than the 0.05 mm a sinking part is allowed."""
    if abs(lift_mm) < SINK_TOLERANCE_MM:
        return None
    return (f"{'lifted' if lift_mm > 0 else 'lowered'} {abs(lift_mm):.{decimals}f} mm so that its lowest point "
            f"rests on the table top")


def check_over_table(wp: Workpiece, fix: str) -> None:
    """Refuse a part that lies wholly beyond the table's rim, seen from above (a file's part at
    x = 5000 mm was scanned, and measured only the table), ``fix`` saying how to place it."""
    from ..kinematics.turntable import beyond_table, nearest_to_axis_mm

    why = beyond_table(f"the workpiece {wp.name}", nearest_to_axis_mm(wp.mesh))
    if why is not None:
        raise InputError(f"{why}: nothing holds it as the table turns; {fix}")


def check_on_table(wp: Workpiece, fix: str) -> None:
    """Refuse a part that reaches more than SINK_TOLERANCE_MM into the table, ``fix`` saying how
    to lift it: the table would hide that surface and its truth would still count it."""
    depth = depth_below_table(wp)
    if depth > SINK_TOLERANCE_MM:
        loose = next((n for n in wp.notes if RESTS_ON_LOOSE in n), None)
        raise InputError(f"the workpiece {wp.name} reaches {depth:.2f} mm below the table top (z = 0 in the table "
                         f"frame): a part rests on the table or on a fixture; {fix}"
                         + ("" if loose is None else f" (its lowest point is a loose piece: {loose.split('; ')[0]})"))
