"""A scan cut into shards by frame range, each shard's result kept in a checksummed file.

A shard is the frames start..stop−1 of the path. Its file (``.npz``) holds the
points it produced (table frame, with frame, camera and quality per point), its
counters (columns seen and kept, per detection code, rows rendered per frame,
frames re-rendered), its stage times, the frame range, the fingerprint of the
scan it belongs to, and a SHA-256 checksum over all of that. Files are written
atomically; a file that is missing, truncated, altered, for other frames or for
another scan is not valid and its shard is computed again.

Merging valid shards in frame order gives the cloud a single process makes: every
frame is computed from the same plan (joint vectors, band predictions) whatever
shard it falls in, and band renders give the rows full frames give bit for bit.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import math
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..geometry.cloud import Cloud
from ..errors import InputError
from ..files import write_bytes_atomic

# 2: table fixtures are rendered (a shard of a config with fixtures written before would lack them)
FORMAT = 2


@dataclass(frozen=True)
class Shard:
    index: int
    start: int
    stop: int

    @property
    def frames(self) -> range:
        return range(self.start, self.stop)

    def file_name(self) -> str:
        return f"shard_{self.start:06d}_{self.stop - 1:06d}.npz"

    def describe(self) -> str:
        return f"shard {self.index} (frames {self.start}-{self.stop - 1})"


def split(n_frames: int, shard_frames: int) -> list[Shard]:
    """Consecutive shards of ``shard_frames`` frames (the last may be shorter)."""
    if isinstance(n_frames, bool) or not isinstance(n_frames, int) or n_frames < 1:
        raise InputError(f"a scan to shard needs at least 1 frame, got {n_frames!r}")
    if isinstance(shard_frames, bool) or not isinstance(shard_frames, int) or shard_frames < 1:
        raise InputError(f"frames per shard must be a whole number of at least 1, got {shard_frames!r}")
    starts = range(0, n_frames, shard_frames)
    return [Shard(i, a, min(a + shard_frames, n_frames)) for i, a in enumerate(starts)]


def default_shard_frames(n_frames: int, workers: int) -> int:
    """About four shards per worker (so a slow or lost worker delays little), at least 4 frames each."""
    return max(4, math.ceil(n_frames / max(4 * workers, 1)))


# Fields of a config that name or describe a scan without changing its result.
NOT_IN_FINGERPRINT = {"name", "source", "description"}


def _feed(h, part) -> None:
    """Hash ``part``: arrays as exact bytes, dataclasses field by field (so that every field a
    config has counts, without a list to keep up to date), meshes by their vertices and faces."""
    if isinstance(part, np.ndarray):
        a = np.ascontiguousarray(part)
        h.update(str((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())
    elif dataclasses.is_dataclass(part) and not isinstance(part, type):
        h.update(type(part).__qualname__.encode())
        for f in dataclasses.fields(part):
            if f.name not in NOT_IN_FINGERPRINT:
                h.update(f.name.encode())
                _feed(h, getattr(part, f.name))
    elif hasattr(part, "vertices") and hasattr(part, "faces"):
        _feed(h, np.asarray(part.vertices))
        _feed(h, np.asarray(part.faces))
    elif isinstance(part, (list, tuple)):
        for item in part:
            _feed(h, item)
    elif isinstance(part, dict):
        for key in sorted(part, key=repr):
            h.update(repr(key).encode())
            _feed(h, part[key])
    else:
        h.update(repr(part).encode())
    h.update(b"\x00")


def fingerprint(parts: list) -> str:
    """SHA-256 of everything that decides a scan's result (numbers as exact bytes, the rest as text)."""
    h = hashlib.sha256()
    for part in parts:
        _feed(h, part)
    return h.hexdigest()


def _checksum(arrays: dict, meta: dict) -> str:
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(name.encode())
        h.update(str((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())
    h.update(json.dumps(meta, sort_keys=True).encode())
    return h.hexdigest()


@dataclass
class ShardResult:
    shard: Shard
    cloud: Cloud
    stats: dict
    timing: dict
    render_device: str | None = None
    blender: str | None = None  # the Blender that rendered it (None: none did, the raycast engine)


def write(path: str | Path, shard: Shard, cloud: Cloud, stats: dict, timing: dict, scan_fingerprint: str,
          render_device: str | None = None, blender: str | None = None) -> Path:
    """Write a shard's result atomically, with its checksum."""
    arrays = {"points": cloud.points, "frame": cloud.frame, "camera": cloud.camera, "quality": cloud.quality,
              "band_rows": np.asarray(stats["band_rows"], dtype=np.int64)}
    meta = {"format": FORMAT, "fingerprint": scan_fingerprint, "start": shard.start, "stop": shard.stop,
            "columns": int(stats["columns"]), "valid": int(stats["valid"]), "rerendered": int(stats["rerendered"]),
            "codes": {k: int(v) for k, v in stats["codes"].items()},
            "points_counts": {k: int(v) for k, v in stats.get("points", {}).items()},  # kept and dropped
            "render_device": render_device, "blender": blender,
            "timing": {k: float(v) for k, v in timing.items()}}
    meta["checksum"] = _checksum(arrays, meta)
    buf = io.BytesIO()
    np.savez(buf, meta=np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8), **arrays)
    return write_bytes_atomic(path, buf.getvalue())


class ShardInvalid(Exception):
    """A shard file that cannot be used; the message says why (missing, damaged, other scan...)."""


def read(path: str | Path, shard: Shard, scan_fingerprint: str) -> ShardResult:
    """Read and check a shard file; raises :class:`ShardInvalid` saying why it cannot be used."""
    path = Path(path)
    if not path.exists():
        raise ShardInvalid("missing")
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(bytes(z["meta"]).decode())
            arrays = {k: z[k] for k in ("points", "frame", "camera", "quality", "band_rows")}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ShardInvalid(f"unreadable ({type(exc).__name__}: truncated or damaged)") from None
    stored = meta.pop("checksum", None)
    if stored != _checksum(arrays, meta):
        raise ShardInvalid("checksum mismatch (altered or damaged)")
    if meta.get("format") != FORMAT:
        raise ShardInvalid(f"format {meta.get('format')} (expected {FORMAT})")
    if meta.get("fingerprint") != scan_fingerprint:
        raise ShardInvalid("from another scan (its config, path or plan differ)")
    if (meta.get("start"), meta.get("stop")) != (shard.start, shard.stop):
        raise ShardInvalid(f"holds frames {meta.get('start')}-{meta.get('stop', 0) - 1}, not "
                           f"{shard.start}-{shard.stop - 1}")
    frames = arrays["frame"]
    if len(arrays["band_rows"]) != shard.stop - shard.start or (
            len(frames) and (frames.min() < shard.start or frames.max() >= shard.stop)):
        raise ShardInvalid("inconsistent (points outside its frames)")
    cloud = Cloud(arrays["points"], frames, arrays["camera"], arrays["quality"])
    stats = {"columns": meta["columns"], "valid": meta["valid"], "rerendered": meta["rerendered"],
             "codes": meta["codes"], "band_rows": arrays["band_rows"].tolist()}
    if meta.get("points_counts"):  # (shards written before this key, or with no points, have none)
        stats["points"] = meta["points_counts"]
    return ShardResult(shard, cloud, stats, meta["timing"], meta.get("render_device"), meta.get("blender"))
