"""Mesh files whose faces are polygons, read as their authors meant them.

Blender's OBJ and PLY exporters keep n-gons by default, and an extruded L-profile's cap is a
concave one. Split into a fan from its first corner, as trimesh splits every polygon, such a
face gains a triangle across its notch: a scan of the part measured its points against
surface the file does not have (a hunt: 297 points in an L's notch read as 1.8 µm RMS). Here
each polygon is split by ear clipping in its own plane, a convex one as a fan (the same
triangles). And an OBJ's negative indices count back from the vertices read so far, as the
format says (trimesh counts them from the end of the file: an OBJ of two objects written so
read as another part).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError


def triangulate(vertices: np.ndarray, polygons) -> np.ndarray:
    """Triangles (m, 3) of ``polygons``: an (m, k) array of vertex indices, or a list of index
    sequences of three or more; triangles and quads at once, larger polygons one by one."""
    V = np.asarray(vertices, dtype=np.float64)
    if isinstance(polygons, np.ndarray) and polygons.ndim == 2:
        groups = {polygons.shape[1]: polygons.astype(np.int64)}
    else:
        sizes: dict = {}
        for poly in polygons:
            sizes.setdefault(len(poly), []).append(poly)
        groups = {k: np.asarray(v, dtype=np.int64) for k, v in sizes.items() if k >= 3}
    out = []
    for k, polys in sorted(groups.items()):
        if k == 3:
            out.append(polys)
        elif k == 4:
            out.append(_quads(V, polys))
        else:
            out += [poly[_split(V[poly])] for poly in polys]
    return np.concatenate(out).astype(np.int64) if out else np.zeros((0, 3), np.int64)


def _quads(V: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """Two triangles per quad (m, 4): across corners 0-2, or 1-3 where 0-2 runs outside (a
    concave quad), so that both turn the quad's own way."""
    P = V[quads]
    normal = np.sum(np.cross(P, np.roll(P, -1, axis=1)), axis=1)
    first = np.einsum("ij,ij->i", np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), normal)
    second = np.einsum("ij,ij->i", np.cross(P[:, 2] - P[:, 0], P[:, 3] - P[:, 0]), normal)
    across = (first < 0) | (second < 0)
    a = np.where(across[:, None], quads[:, [1, 2, 3]], quads[:, [0, 1, 2]])
    b = np.where(across[:, None], quads[:, [1, 3, 0]], quads[:, [0, 2, 3]])
    return np.stack([a, b], axis=1).reshape(-1, 3)


def _split(P: np.ndarray) -> np.ndarray:
    """Corner triples (n - 2, 3) splitting the polygon with corners P (n, 3), in order."""
    n = len(P)
    fan = np.column_stack([np.zeros(n - 2, int), np.arange(1, n - 1), np.arange(2, n)])
    # Newell's normal: the polygon's plane, whatever its winding or a few corners in line.
    normal = np.sum(np.cross(P, np.roll(P, -1, axis=0)), axis=0)
    size = float(np.linalg.norm(normal))
    if not np.isfinite(size) or size == 0.0:
        return fan  # no area: nothing to get right
    normal /= size
    u = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    Q = np.column_stack([P @ u, P @ v])  # counter-clockwise about the normal
    turn = _cross(np.roll(Q, 1, axis=0), Q, np.roll(Q, -1, axis=0))
    if np.all(turn >= 0.0):
        return fan  # convex: every fan triangle lies inside
    return _ears(Q, fan)


def _cross(a, b, c):
    """The z of (b - a) × (c - b): positive where the path a → b → c turns left."""
    return (b[..., 0] - a[..., 0]) * (c[..., 1] - b[..., 1]) - (b[..., 1] - a[..., 1]) * (c[..., 0] - b[..., 0])


def _ears(Q: np.ndarray, fan: np.ndarray) -> np.ndarray:
    """Ear clipping of the counter-clockwise polygon Q (n, 2); the fan where it finds no ear (a
    polygon that crosses itself has no right split)."""
    left = list(range(len(Q)))
    tris = []
    scale = float(np.ptp(Q, axis=0).max()) or 1.0
    eps = 1e-12 * scale * scale
    while len(left) > 3:
        k = len(left)
        for j in range(k):
            a, b, c = left[j - 1], left[j], left[(j + 1) % k]
            if _cross(Q[a], Q[b], Q[c]) <= eps:
                continue  # a reflex (or straight) corner is no ear
            others = [i for i in left if i not in (a, b, c)]
            R = Q[others]
            # A corner at the same place as one of the ear's (a vertex written twice, a hole's
            # bridge) does not block it: counted inside, it left no ear and the fan came back.
            apart = np.min([np.sum((R - Q[k]) ** 2, axis=1) for k in (a, b, c)], axis=0) > eps
            inside = apart & (_cross(Q[a], Q[b], R) >= -eps) & (_cross(Q[b], Q[c], R) >= -eps) \
                & (_cross(Q[c], Q[a], R) >= -eps)
            if not inside.any():
                tris.append((a, b, c))
                del left[j]
                break
        else:
            return fan
    tris.append(tuple(left))
    return np.asarray(tris, dtype=np.int64)


def needs_own_obj_reader(path: Path) -> bool:
    """Whether an OBJ holds a face of more than three corners or a negative index: what
    trimesh's reader gets wrong (fans, and negative indices counted from the file's end)."""
    with open(path, "rb") as f:
        for line in f:
            if line[:2] == b"f " or line[:2] == b"f\t":
                words = line.split()[1:]
                if len(words) > 3 or any(w.startswith(b"-") for w in words):
                    return True
    return False


def read_obj(path: str | Path) -> tuple[np.ndarray, list]:
    """(vertices (n, 3), polygons) of an OBJ: its ``v`` and ``f`` lines, every object's faces,
    negative indices counted back from the vertices read before the face (as the format says).
    InputError for a face that names a vertex not there."""
    path = Path(path)
    vertices, polygons = [], []
    pending, highest = b"", (-1, 0)
    with open(path, "rb") as f:
        for number, raw in enumerate(f, start=1):
            raw = pending + raw
            if raw.rstrip().endswith(b"\\"):  # a line continued on the next
                pending = raw.rstrip()[:-1] + b" "
                continue
            pending = b""
            words = raw.split()
            if not words:
                continue
            if words[0] == b"v":
                try:
                    vertices.append([float(w) for w in words[1:4]])
                except ValueError:
                    raise InputError(f"{path}: line {number}: a vertex needs three numbers, got "
                                     f"{raw.decode(errors='replace').strip()!r}") from None
                if len(vertices[-1]) != 3:
                    raise InputError(f"{path}: line {number}: a vertex needs three numbers")
            elif words[0] == b"f":
                poly = []
                for w in words[1:]:
                    try:
                        i = int(w.split(b"/")[0])
                    except ValueError:
                        raise InputError(f"{path}: line {number}: a face corner {w.decode(errors='replace')!r} "
                                         f"is not a vertex number") from None
                    at = i - 1 if i > 0 else len(vertices) + i  # (a positive one may name a vertex written later)
                    if i == 0 or at < 0:
                        raise InputError(f"{path}: line {number} names vertex {i}, and an OBJ counts its vertices "
                                         f"from 1 (or from -1 back, {len(vertices)} written before it); export it "
                                         f"again")
                    poly.append(at)
                    highest = max(highest, (at, number))
                if len(poly) >= 3:
                    polygons.append(poly)
    if highest[0] >= len(vertices):
        raise InputError(f"{path}: line {highest[1]} names vertex {highest[0] + 1}, and the file has only "
                         f"{len(vertices)}; export it again")
    return np.asarray(vertices, dtype=np.float64).reshape(-1, 3), polygons
