"""Reading the uncompressed OpenEXR files the probe renders are written as.

Why a reader of our own: Blender 4.5 loads multiview EXR files (``*_L.exr``,
``*_R.exr``) through ``bpy.data.images`` as 0 × 0 images, and the OpenCV 5 wheels
are built without OpenEXR. The renders are written by ``addon.scene.render`` as
single-part scanline images with compression NONE, so reading them is a header
walk and one ``numpy.frombuffer`` per scanline block. Anything else (compressed,
tiled, deep, multi-part) is refused with a message that says so.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from .errors import InputError

MAGIC = 20000630
_FLAG_TILED, _FLAG_DEEP, _FLAG_MULTIPART = 0x200, 0x800, 0x1000
_PIXEL_DTYPES = {0: np.dtype("<u4"), 1: np.dtype("<f2"), 2: np.dtype("<f4")}
_COMPRESSION_NONE = 0


def _cstring(buf: bytes, pos: int, path) -> tuple[str, int]:
    end = buf.find(b"\0", pos)
    if end < 0:
        raise InputError(f"{path}: not a readable OpenEXR file (header cut short)")
    return buf[pos:end].decode("latin-1"), end + 1


def _channels(value: bytes, path) -> list[tuple[str, np.dtype]]:
    out, pos = [], 0
    while pos < len(value) and value[pos] != 0:
        name, pos = _cstring(value, pos, path)
        pixel_type, _, _, x_sampling, y_sampling = struct.unpack_from("<iB3sii", value, pos)
        pos += 16
        if pixel_type not in _PIXEL_DTYPES or (x_sampling, y_sampling) != (1, 1):
            raise InputError(f"{path}: channel {name!r} has pixel type {pixel_type} sampled "
                             f"{x_sampling}x{y_sampling}; only full-resolution half/float/uint channels are read")
        out.append((name, _PIXEL_DTYPES[pixel_type]))
    return out


def read_exr(path: str | Path, channels: tuple[str, ...] = ("R", "G", "B")) -> np.ndarray:
    """An uncompressed scanline OpenEXR file -> (H, W, len(channels)) float32, row 0 at the top.

    channels : the channel names to return, in this order (each must be in the file).
    """
    buf = Path(path).read_bytes()
    try:
        return _parsed(buf, path, channels)
    except InputError:  # (a ValueError too) already says what is wrong
        raise
    except (struct.error, ValueError, IndexError, OverflowError):  # a field or table running past the end
        raise InputError(f"{path}: not a readable OpenEXR file (damaged or cut short)") from None


def _parsed(buf: bytes, path, channels: tuple[str, ...]) -> np.ndarray:
    if len(buf) < 8 or struct.unpack_from("<i", buf, 0)[0] != MAGIC:
        raise InputError(f"{path}: not an OpenEXR file")
    flags = struct.unpack_from("<i", buf, 4)[0]
    if flags & (_FLAG_TILED | _FLAG_DEEP | _FLAG_MULTIPART):
        raise InputError(f"{path}: tiled, deep or multi-part OpenEXR files are not read (write scanline images)")
    pos, header = 8, {}
    while True:
        if pos >= len(buf):
            raise InputError(f"{path}: not a readable OpenEXR file (header cut short)")
        if buf[pos] == 0:
            pos += 1
            break
        name, pos = _cstring(buf, pos, path)
        kind, pos = _cstring(buf, pos, path)
        (size,) = struct.unpack_from("<i", buf, pos)
        pos += 4
        header[name] = (kind, buf[pos:pos + size])
        pos += size
    try:
        chans = _channels(header["channels"][1], path)
        compression = header["compression"][1][0]
        x0, y0, x1, y1 = struct.unpack("<iiii", header["dataWindow"][1])
    except KeyError as exc:
        raise InputError(f"{path}: OpenEXR header lacks the required attribute {exc}") from None
    if compression != _COMPRESSION_NONE:
        raise InputError(f"{path}: OpenEXR compression {compression} is not read; write with codec NONE")
    width, height = x1 - x0 + 1, y1 - y0 + 1
    missing = [c for c in channels if c not in [n for n, _ in chans]]
    if missing:
        raise InputError(f"{path}: OpenEXR file has no channel {missing[0]!r} (has {[n for n, _ in chans]})")
    # One scanline per block without compression: an offset table of H uint64, then per block
    # (y: int32, byte count: int32, each channel's W values in the header's channel order).
    offsets = np.frombuffer(buf, dtype="<u8", count=height, offset=pos)
    line_bytes = sum(width * dt.itemsize for _, dt in chans)
    out = np.empty((height, width, len(channels)), dtype=np.float32)
    for block_start in offsets:
        y, size = struct.unpack_from("<ii", buf, int(block_start))
        row = y - y0
        if size != line_bytes or not 0 <= row < height or int(block_start) + 8 + size > len(buf):
            raise InputError(f"{path}: OpenEXR scanline block at byte {block_start} is damaged or cut short")
        at = int(block_start) + 8
        for name, dt in chans:
            if name in channels:
                out[row, :, channels.index(name)] = np.frombuffer(buf, dtype=dt, count=width, offset=at)
            at += width * dt.itemsize
    return out
