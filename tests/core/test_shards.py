"""Shard files: split, write and read back, and every way a file can be unusable."""

import numpy as np
import pytest

from addon.core.scan import shards
from addon.core.geometry.cloud import Cloud
from addon.core.errors import InputError


def sample(shard, seed=0):
    rng = np.random.default_rng(seed)
    n = 50
    cloud = Cloud(rng.normal(size=(n, 3)) * 40, rng.integers(shard.start, shard.stop, n), rng.integers(1, 4, n),
                  rng.random(n))
    stats = {"columns": 640, "valid": 600, "rerendered": 1, "band_rows": [40] * (shard.stop - shard.start),
             "codes": {"OK": 600, "NO_LINE": 40}}
    return cloud, stats, {"render": 0.5, "detect": 0.1}


def test_split_covers_the_path_once():
    parts = shards.split(23, 5)
    assert [(s.start, s.stop) for s in parts] == [(0, 5), (5, 10), (10, 15), (15, 20), (20, 23)]
    assert [s.index for s in parts] == list(range(5))
    assert shards.default_shard_frames(180, 2) == 23 and shards.default_shard_frames(10, 8) == 4
    for bad in ((0, 5), (10, 0), (10, 2.5), (True, 3)):
        with pytest.raises(InputError):
            shards.split(*bad)


def test_round_trip_is_exact(tmp_path):
    s = shards.Shard(2, 10, 15)
    cloud, stats, timing = sample(s)
    path = shards.write(tmp_path / s.file_name(), s, cloud, stats, timing, "f" * 64)
    back = shards.read(path, s, "f" * 64)
    for name in ("points", "frame", "camera", "quality"):
        np.testing.assert_array_equal(getattr(back.cloud, name), getattr(cloud, name))
    assert back.stats == stats and back.timing == timing
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left behind


@pytest.mark.parametrize("damage,reason", [
    (lambda p: p.unlink(), "missing"),
    (lambda p: p.write_bytes(p.read_bytes()[: len(p.read_bytes()) // 2]), "unreadable"),
    (lambda p: p.write_bytes(b""), "unreadable"),
])
def test_missing_and_truncated_files_are_not_valid(tmp_path, damage, reason):
    s = shards.Shard(0, 0, 5)
    path = shards.write(tmp_path / s.file_name(), s, *sample(s), "a" * 64)
    damage(path)
    with pytest.raises(shards.ShardInvalid, match=reason):
        shards.read(path, s, "a" * 64)


def test_altered_points_fail_the_checksum(tmp_path):
    s = shards.Shard(0, 0, 5)
    cloud, stats, timing = sample(s)
    path = shards.write(tmp_path / s.file_name(), s, cloud, stats, timing, "a" * 64)
    # Rewrite the file with one coordinate changed but the old checksum kept.
    with np.load(path) as z:
        arrays = {k: z[k].copy() for k in z.files}
    arrays["points"][3, 1] += 1e-9
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)
    with pytest.raises(shards.ShardInvalid, match="checksum"):
        shards.read(path, s, "a" * 64)


def test_other_scans_and_other_frames_are_not_valid(tmp_path):
    s = shards.Shard(1, 5, 10)
    path = shards.write(tmp_path / s.file_name(), s, *sample(s), "a" * 64)
    with pytest.raises(shards.ShardInvalid, match="another scan"):
        shards.read(path, s, "b" * 64)
    with pytest.raises(shards.ShardInvalid, match="holds frames 5-9"):
        shards.read(path, shards.Shard(1, 5, 11), "a" * 64)


def test_fingerprint_sees_every_bit():
    q = np.linspace(0, 1, 12).reshape(2, 6)
    a = shards.fingerprint([q, "gauss", 1.5])
    q2 = q.copy()
    q2[1, 5] = np.nextafter(q2[1, 5], 2.0)
    assert shards.fingerprint([q2, "gauss", 1.5]) != a
    assert shards.fingerprint([q, "gauss", 1.5]) == a
    assert shards.fingerprint([q, "cog", 1.5]) != a


def test_the_scan_fingerprint_comes_from_every_field_of_the_config():
    from dataclasses import fields, replace

    from addon.core.config.scan import ScanConfig, load_scan_config
    from addon.core.scan.shards import NOT_IN_FINGERPRINT

    a, b = load_scan_config("demo"), load_scan_config("demo")
    assert shards.fingerprint([a]) == shards.fingerprint([b])  # loaded twice: the same scan
    assert shards.fingerprint([a]) == shards.fingerprint([replace(a, name="renamed", description="x")])
    changed = {"roughness": 0.7, "coverage_tolerance_mm": 2.0, "fuse": False, "material": "dark",
               "triangulate_method": "paper", "detect_method": "cog", "probe": a.probe.with_resolution(100, 100)}
    for name, value in changed.items():
        assert shards.fingerprint([replace(a, **{name: value})]) != shards.fingerprint([a]), name
    assert {f.name for f in fields(ScanConfig)} > set(changed) | NOT_IN_FINGERPRINT


def test_shards_of_another_release_are_not_merged(monkeypatch):
    """The scan's fingerprint holds the simulator's release: shards made by another one (whose
    detection or triangulation may differ) are computed again instead of merged with this one's."""
    from addon.core.config.scan import load_scan_config
    from addon.core.scan import outputs
    from addon.pipeline import plan_scan
    from headless import farm

    config = load_scan_config("demo").with_overrides(frames=slice(0, 3), engine="raycast")
    plan = plan_scan(config)
    here = farm.scan_fingerprint(config, plan)
    assert farm.scan_fingerprint(config, plan) == here
    monkeypatch.setattr(outputs, "simulator_version", lambda: "0.0.1")
    assert farm.scan_fingerprint(config, plan) != here
