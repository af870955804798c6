"""Binary PLY files whose faces mix polygon sizes, which trimesh cannot read.

Blender's own PLY exporter writes binary by default and keeps n-gons (a cylinder's caps are
32-gons beside its quads); trimesh reads a binary face list only where every face has as
many corners as the first ("PLY is unexpected length!"). This reads such a file's vertices
and faces itself and leaves the rest to trimesh: the faces are fanned into triangles as
trimesh fans an ASCII file's, so the same mesh saved either way gives the same part.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError

TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
         "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
         "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
MAX_HEADER_BYTES = 1 << 16


def _header(data: bytes, path: Path) -> tuple[str, list, int]:
    """(byte order "<" or ">", [(element, count, [(property, dtype or (count dtype, item dtype))])],
    where the data starts), or None where the file is not a binary PLY."""
    end = data.find(b"end_header", 0, MAX_HEADER_BYTES)
    if not data.startswith(b"ply") or end < 0:
        return None
    start = data.index(b"\n", end) + 1
    order, elements = None, []
    for raw in data[:end].decode("ascii", "replace").splitlines():
        words = raw.split()
        if not words:
            continue
        if words[0] == "format":
            order = {"binary_little_endian": "<", "binary_big_endian": ">"}.get(words[1] if len(words) > 1 else "")
        elif words[0] == "element" and len(words) == 3:
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property" and elements:
            try:
                if words[1] == "list":
                    kind = (np.dtype(TYPES[words[2]]), np.dtype(TYPES[words[3]]))
                else:
                    kind = np.dtype(TYPES[words[1]])
            except (KeyError, IndexError):
                raise InputError(f"{path}: a PLY property the reader does not know: {raw.strip()!r}") from None
            elements[-1][2].append((words[-1], kind))
    if order is None:
        return None
    return order, elements, start


def read_polygon_ply(path: str | Path):
    """(vertices (n, 3) float64, faces (m, 3) int64 triangles) of a binary PLY whose faces may mix
    polygon sizes; None where the file is not a binary PLY with vertices and faces this reads
    (trimesh's word stands then)."""
    path = Path(path)
    data = path.read_bytes()
    head = _header(data, path)
    if head is None:
        return None
    order, elements, at = head
    try:
        return _read(data, order, elements, at, path)
    except ValueError:  # numpy's "buffer is smaller than requested size"
        raise InputError(f"{path}: the binary PLY holds fewer bytes than its header announces: the file is cut "
                         f"short; export it again") from None


def _read(data: bytes, order: str, elements: list, at: int, path: Path):
    import trimesh

    vertices = polygons = None
    for name, count, props in elements:
        fixed = all(not isinstance(kind, tuple) for _, kind in props)
        if fixed:
            dtype = np.dtype([(p, kind.newbyteorder(order)) for p, kind in props])
            block = np.frombuffer(data, dtype=dtype, count=count, offset=at)
            at += count * dtype.itemsize
            if name == "vertex":
                if not {"x", "y", "z"} <= set(dtype.names):
                    return None
                vertices = np.column_stack([block[c].astype(np.float64) for c in "xyz"])
            continue
        if name != "face" or len(props) != 1:
            return None  # lists elsewhere, or beside other face properties: not this reader's case
        count_type, item_type = (k.newbyteorder(order) for k in props[0][1])
        polygons, view = [], memoryview(data)
        for _ in range(count):
            n = int(np.frombuffer(view, dtype=count_type, count=1, offset=at)[0])
            at += count_type.itemsize
            polygons.append(np.frombuffer(view, dtype=item_type, count=n, offset=at).astype(np.int64))
            at += n * item_type.itemsize
    if vertices is None or polygons is None:
        return None
    bad = [p for p in polygons if len(p) < 3 or p.min(initial=0) < 0 or p.max(initial=0) >= len(vertices)]
    if bad:
        raise InputError(f"{path}: {len(bad)} of its {len(polygons)} faces name fewer than three corners or corners "
                         f"beyond its {len(vertices)} vertices")
    return vertices, np.asarray(trimesh.geometry.triangulate_quads(polygons), dtype=np.int64).reshape(-1, 3)
