"""Point clouds in the workpiece (table) frame, built frame by frame (paper Eq. 8).

Each frame's profile is measured in the probe frame; ``probe2table`` =
``base2table(θ_R) @ probe2base(q)`` (see :mod:`addon.core.kinematics.cell`) takes it into the
table frame, where clouds from every frame, table angle and camera accumulate.
Every point keeps the frame it came from, which camera(s) saw it and its
quality (its depth uncertainty σ in mm: see optics.triangulate).

PLY files are binary, written through trimesh, with per-vertex properties
``frame`` (int), ``camera`` (uchar: 1, 2 or 3 = both) and ``quality`` (float, mm).
PLY stores coordinates as float32: at 500 mm that is a quantisation of 0.03 µm.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from ..errors import InputError, ScannerError
from ..files import write_bytes_atomic
from ..kinematics.transforms import check_transform
from ..optics.triangulate import Profile


@dataclass
class Cloud:
    """points (n, 3) mm table frame; frame (n,) int32; camera (n,) uint8; quality (n,) float32 mm."""

    points: np.ndarray
    frame: np.ndarray
    camera: np.ndarray
    quality: np.ndarray

    def __post_init__(self) -> None:
        self.points = np.asarray(self.points, dtype=np.float64).reshape(-1, 3)
        n = len(self.points)
        self.frame = np.asarray(self.frame, dtype=np.int32).reshape(n)
        self.camera = np.asarray(self.camera, dtype=np.uint8).reshape(n)
        self.quality = np.asarray(self.quality, dtype=np.float32).reshape(n)

    def __len__(self) -> int:
        return len(self.points)

    @staticmethod
    def empty() -> "Cloud":
        return Cloud(np.zeros((0, 3)), np.zeros(0), np.zeros(0), np.zeros(0))

    @staticmethod
    def concatenate(clouds: list["Cloud"]) -> "Cloud":
        if not clouds:
            return Cloud.empty()
        return Cloud(np.concatenate([c.points for c in clouds]), np.concatenate([c.frame for c in clouds]),
                     np.concatenate([c.camera for c in clouds]), np.concatenate([c.quality for c in clouds]))

    def select(self, keep) -> "Cloud":
        return Cloud(self.points[keep], self.frame[keep], self.camera[keep], self.quality[keep])


def profile_to_table(profile: Profile, probe2table, frame: int) -> Cloud:
    """One frame's profile (probe frame) -> its points in the table frame (Eq. 8)."""
    T = check_transform(probe2table, "probe2table")
    pts = profile.points @ T[:3, :3].T + T[:3, 3]
    return Cloud(pts, np.full(len(pts), frame), profile.camera, profile.sigma_mm)


class CloudAccumulator:
    """Collects frames' profiles into one cloud in the table frame."""

    def __init__(self) -> None:
        self._parts: list[Cloud] = []

    def add(self, profile: Profile, probe2table, frame: int) -> Cloud:
        part = profile_to_table(profile, probe2table, frame)
        self._parts.append(part)
        return part

    def cloud(self) -> Cloud:
        return Cloud.concatenate(self._parts)


def ply_bytes(cloud: Cloud) -> bytes:
    """The cloud as a binary PLY with frame, camera and quality per point."""
    mesh = trimesh.Trimesh(vertices=cloud.points, faces=np.zeros((0, 3), dtype=np.int64), process=False)
    mesh.vertex_attributes["frame"] = cloud.frame
    mesh.vertex_attributes["camera"] = cloud.camera
    mesh.vertex_attributes["quality"] = cloud.quality
    return mesh.export(file_type="ply", encoding="binary")


def save_ply(cloud: Cloud, path: str | Path) -> Path:
    """Write the cloud as a binary PLY (see ply_bytes), atomically."""
    return write_bytes_atomic(path, ply_bytes(cloud))


def _vertex_count(path: Path) -> int | None:
    """The vertex count a PLY file's header declares (None: no such line in its first lines)."""
    with open(path, "rb") as fh:
        for _ in range(64):
            line = fh.readline()
            if not line or line.strip() == b"end_header":
                return None
            words = line.split()
            if words[:2] == [b"element", b"vertex"] and len(words) == 3 and words[2].isdigit():
                return int(words[2])
    return None


def load_ply(path: str | Path) -> Cloud:
    """Read a PLY point cloud; frame, camera and quality default to 0 when absent."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    try:
        loaded = trimesh.load(path, file_type="ply", process=False)
    except Exception as exc:  # trimesh raises many kinds for a bad file
        raise ScannerError(f"{path}: not a readable PLY file ({type(exc).__name__}: {exc})") from None
    if not hasattr(loaded, "vertices"):
        # trimesh reads a PLY with no vertices (an empty cloud, as a scan that measured
        # nothing writes) as an empty Scene
        if getattr(loaded, "is_empty", False) and _vertex_count(path) == 0:
            return Cloud.empty()
        raise ScannerError(f"{path}: not a point cloud (trimesh read a {type(loaded).__name__})")
    raw = getattr(loaded, "metadata", {}).get("_ply_raw", {}).get("vertex", {}).get("data")
    points = np.asarray(loaded.vertices, dtype=np.float64)
    n = len(points)

    # A binary file's vertex data is one structured array; an ASCII file's, a dict of columns.
    names = (raw.keys() if isinstance(raw, dict) else (raw.dtype.names or ())) if raw is not None else ()

    def field(name, dtype):
        if name in names:
            column = np.asarray(raw[name])
            if column.size == n:
                return column.astype(dtype).reshape(n)
        return np.zeros(n, dtype=dtype)

    return Cloud(points, field("frame", np.int32), field("camera", np.uint8), field("quality", np.float32))
