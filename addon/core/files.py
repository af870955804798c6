"""Writing output files so that a failed run never leaves a half-written one."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def write_bytes_atomic(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to a temporary file beside ``path`` and rename it into place.

    A crash or error mid-way leaves the old file (or none), never a partial one.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the file the usual mode
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def write_png(path: str | Path, bgr) -> Path:
    """Encode a BGR uint8 picture as PNG and write it atomically."""
    import cv2

    from .errors import ScannerError

    ok, png = cv2.imencode(".png", bgr)
    if not ok:
        raise ScannerError(f"could not encode the picture for {path}")
    return write_bytes_atomic(path, png.tobytes())


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
