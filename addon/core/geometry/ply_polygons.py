"""PLY files read face by face: polygons of any size, in binary and in ASCII.

Blender's own PLY exporter keeps n-gons (a cylinder's caps are 32-gons beside its quads, an
L-profile's caps concave). trimesh reads a binary face list only where every face has as
many corners as the first ("PLY is unexpected length!"), and splits every polygon into a fan
from its first corner, which puts a triangle across a concave face's notch. This reads the
vertices and the faces' corner lists itself (beside other face properties, such as colours)
and leaves the splitting to polygons.triangulate; trimesh reads what this does not.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..errors import InputError

TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
         "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
         "int64": "i8", "uint64": "u8", "float16": "f2", "half": "f2",
         "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
MAX_HEADER_BYTES = 1 << 16
END_HEADER = re.compile(rb"^end_header[ \t]*\r?$", re.MULTILINE)  # the line, not the word in a comment
BOM = b"\xef\xbb\xbf"


class _NotOurs(Exception):
    """A header this reader does not know (a property type of its own): trimesh reads the file."""


def _header(data: bytes, path: Path) -> tuple[str, list, int]:
    """(byte order "<" or ">", [(element, count, [(property, dtype or (count dtype, item dtype))])],
    where the data starts), or None where the file is not a binary PLY."""
    found = END_HEADER.search(data, 0, MAX_HEADER_BYTES)
    if not data.startswith(b"ply") or found is None:
        return None
    start = found.end() + 1  # (the newline after it)
    order, elements = None, []  # order "" for ASCII
    for raw in data[:found.start()].decode("ascii", "replace").splitlines():
        words = raw.split()
        if not words:
            continue
        if words[0] == "format":
            order = {"binary_little_endian": "<", "binary_big_endian": ">", "ascii": ""}.get(
                words[1] if len(words) > 1 else "")
        elif words[0] == "element" and len(words) == 3:
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property" and elements:
            try:
                if words[1] == "list":
                    kind = (np.dtype(TYPES[words[2]]), np.dtype(TYPES[words[3]]))
                else:
                    kind = np.dtype(TYPES[words[1]])
            except (KeyError, IndexError):
                raise _NotOurs(raw.strip()) from None  # (refused before: trimesh read such files)
            elements[-1][2].append((words[-1], kind))
    if order is None:
        return None
    return order, elements, start


def _check_vertex_properties(elements: list, path: Path) -> None:
    """InputError where the header's vertices lack x, y or z (trimesh said "KeyError: 'y'")."""
    vertex = [props for name, _, props in elements if name == "vertex"]
    names = [name for name, _ in vertex[0]] if vertex else []
    missing = [c for c in "xyz" if c not in names]
    if missing:
        raise InputError(f"{path}: its vertices have no {' or '.join(missing)} "
                         f"({'properties: ' + ', '.join(names) if vertex else 'no vertex element'}): a mesh's "
                         f"vertices need x, y and z")


def _first_non_number(data: bytes, at: int) -> tuple[int, str] | None:
    """(line number, word) of the first word after the header (at byte ``at``) that is no
    number, or None."""
    first_line = data.count(b"\n", 0, at) + 1
    for k, line in enumerate(data[at:].splitlines()):
        for word in line.split():
            try:
                float(word)
            except ValueError:
                return first_line + k, word.decode("ascii", "replace")
    return None


def read_polygon_ply(path: str | Path):
    """(vertices (n, 3) float64, polygons: a list of index arrays) of a PLY; None where this
    reader does not read it (a header longer than MAX_HEADER_BYTES, a property type or format
    of its own: trimesh's word stands then). InputError, in plain words, where the file is no
    PLY mesh: it does not begin with "ply", it ends inside its header, its vertices lack x, y
    or z, or its data is cut short or holds a word that is no number (trimesh said
    "IndexError: list index out of range" or "KeyError: 'y'" for some of these)."""
    path = Path(path)
    data = path.read_bytes()
    if data.startswith(BOM):  # (some Windows tools write one; trimesh reads past it too)
        data = data[len(BOM):]
    if not data.startswith(b"ply"):
        raise InputError(f"{path}: not a PLY file (a PLY begins with the word ply); is it another format, or "
                         f"no mesh at all?")
    if END_HEADER.search(data) is None:
        raise InputError(f"{path}: the file ends inside its PLY header (no end_header line): it is cut short or "
                         f"damaged; export it again")
    try:
        head = _header(data, path)
    except _NotOurs:
        return None
    if head is None:
        return None
    order, elements, at = head
    _check_vertex_properties(elements, path)
    try:
        got = _read(data, order, elements, at, path) if order else _read_ascii(data, elements, at, path)
    except (ValueError, IndexError):  # numpy's "buffer is smaller than requested size"; text cut short
        odd = None if order else _first_non_number(data, at)
        if odd is not None:
            raise InputError(f"{path}: line {odd[0]} holds {odd[1]!r} where the PLY's header announces numbers; "
                             f"export it again") from None
        what = "the binary PLY holds fewer bytes" if order else "the PLY's text holds fewer numbers"
        raise InputError(f"{path}: {what} than its header announces: the file is cut short; export it "
                         f"again") from None
    if got is None:
        return None
    vertices, polygons = got
    if isinstance(polygons, np.ndarray):
        bad = int(np.sum((polygons < 0).any(axis=1) | (polygons >= len(vertices)).any(axis=1))) \
            if polygons.shape[1] >= 3 else len(polygons)
    else:
        bad = sum(1 for p in polygons if len(p) < 3 or p.min(initial=0) < 0 or p.max(initial=0) >= len(vertices))
    if bad:
        raise InputError(f"{path}: {bad} of its {len(polygons)} faces name fewer than three corners or corners "
                         f"beyond its {len(vertices)} vertices; export it again")
    return vertices, polygons


def _read_ascii(data: bytes, elements: list, at: int, path: Path):
    words = data[at:].split()
    i, vertices, polygons = 0, None, None
    for name, count, props in elements:
        if name == "vertex":
            if any(isinstance(kind, tuple) for _, kind in props) or not {"x", "y", "z"} <= {p for p, _ in props}:
                return None
            n = len(props)
            block = np.asarray(words[i:i + count * n], dtype=np.float64).reshape(count, n)
            i += count * n
            cols = [p for p, _ in props]
            vertices = block[:, [cols.index(c) for c in "xyz"]]
        elif name == "face":
            polygons = []
            for _ in range(count):
                for prop, kind in props:
                    if isinstance(kind, tuple):
                        k = int(words[i])
                        corners = np.asarray(words[i + 1:i + 1 + k], dtype=np.int64)
                        if len(corners) != k:
                            raise IndexError
                        i += 1 + k
                        if prop in ("vertex_indices", "vertex_index"):
                            polygons.append(corners)
                    else:
                        i += 1
        else:
            width = sum(1 for _, kind in props if not isinstance(kind, tuple))
            if width != len(props):
                return None  # lists in another element: not this reader's case
            i += count * width
    if vertices is None or polygons is None or len(polygons) != next(c for n, c, _ in elements if n == "face"):
        return None
    return vertices, polygons


def _read(data: bytes, order: str, elements: list, at: int, path: Path):
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
        lists = [(p, kind) for p, kind in props if isinstance(kind, tuple)]
        if name != "face" or len(lists) != 1 or lists[0][0] not in ("vertex_indices", "vertex_index"):
            return None  # lists elsewhere: not this reader's case
        view = memoryview(data)
        # Every face of one size (all triangles, say), beside other face properties or not: the
        # rows read at once, as a record each.
        fields, first, skip = [], None, at
        for prop, kind in props:
            if isinstance(kind, tuple):
                count_type, item_type = (k.newbyteorder(order) for k in kind)
                first = int(np.frombuffer(view, dtype=count_type, count=1, offset=skip)[0]) if count else 0
                fields += [("n", count_type), ("i", item_type, (max(first, 1),))]
                skip += count_type.itemsize + first * item_type.itemsize
            else:
                fields.append((f"_{len(fields)}", kind.newbyteorder(order)))
                skip += kind.itemsize
        row = np.dtype(fields)
        if count and first and at + count * row.itemsize <= len(data):
            block = np.frombuffer(view, dtype=row, count=count, offset=at)
            if np.all(block["n"] == first):
                polygons = block["i"].astype(np.int64).reshape(count, first)
                at += count * row.itemsize
                continue
        polygons = []
        for _ in range(count):
            for prop, kind in props:
                if isinstance(kind, tuple):
                    count_type, item_type = (k.newbyteorder(order) for k in kind)
                    n = int(np.frombuffer(view, dtype=count_type, count=1, offset=at)[0])
                    at += count_type.itemsize
                    polygons.append(np.frombuffer(view, dtype=item_type, count=n, offset=at).astype(np.int64))
                    at += n * item_type.itemsize
                else:
                    at += kind.itemsize
    if vertices is None or polygons is None:
        return None
    return vertices, polygons
