"""The EXR reader against files built byte by byte from the OpenEXR layout (not by the reader's code)."""

import struct

import numpy as np
import pytest

from addon.core.errors import InputError
from addon.core.exr import read_exr


def attr(name, kind, value):
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value


def exr_bytes(channels, y0=0, compression=0, flags=2):
    """channels: {name: (H, W) array of float16/float32}; scanline, one line per block."""
    names = sorted(channels)
    H, W = channels[names[0]].shape
    chlist = b"".join(n.encode() + b"\0" + struct.pack("<iB3sii", 1 if channels[n].dtype == np.float16 else 2,
                                                          0, b"\0\0\0", 1, 1) for n in names) + b"\0"
    box = struct.pack("<iiii", 0, y0, W - 1, y0 + H - 1)
    header = (struct.pack("<ii", 20000630, flags) + attr("channels", "chlist", chlist)
              + attr("compression", "compression", bytes([compression])) + attr("dataWindow", "box2i", box)
              + attr("displayWindow", "box2i", box) + attr("lineOrder", "lineOrder", b"\0")
              + attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
              + attr("screenWindowCenter", "v2f", struct.pack("<ff", 0, 0))
              + attr("screenWindowWidth", "float", struct.pack("<f", 1.0)) + b"\0")
    blocks = []
    for row in range(H):
        data = b"".join(channels[n][row].astype(channels[n].dtype.newbyteorder("<")).tobytes() for n in names)
        blocks.append(struct.pack("<ii", y0 + row, len(data)) + data)
    # Blocks stored bottom-up: the offset table, not the storage order, must locate them.
    table, body, pos = [0] * H, b"", len(header) + 8 * H
    for row in reversed(range(H)):
        table[row] = pos
        body += blocks[row]
        pos += len(blocks[row])
    return header + struct.pack(f"<{H}Q", *table) + body


@pytest.fixture
def rgb():
    rng = np.random.default_rng(3)
    return {c: rng.random((5, 7)).astype(np.float32) for c in "RGB"}


def test_float_channels_come_back_exactly_top_row_first(tmp_path, rgb):
    path = tmp_path / "a.exr"
    path.write_bytes(exr_bytes(rgb, y0=12))  # a cropped data window starting at row 12
    img = read_exr(path)
    assert img.shape == (5, 7, 3) and img.dtype == np.float32
    np.testing.assert_array_equal(img, np.dstack([rgb["R"], rgb["G"], rgb["B"]]))


def test_half_channels_and_extra_channels(tmp_path, rgb):
    chans = {c: v.astype(np.float16) for c, v in rgb.items()}
    chans["A"] = np.ones((5, 7), np.float16)
    path = tmp_path / "h.exr"
    path.write_bytes(exr_bytes(chans))
    np.testing.assert_array_equal(read_exr(path)[..., 1], rgb["G"].astype(np.float16).astype(np.float32))
    np.testing.assert_array_equal(read_exr(path, ("A",))[..., 0], 1.0)


@pytest.mark.parametrize("damage, message", [
    (lambda b: b"\x89PNG" + b[4:], "not an OpenEXR file"),
    (lambda b: b[:40], "cut short"),
    (lambda b: b[:-10], "damaged or cut short"),
])
def test_damaged_files_are_named(tmp_path, rgb, damage, message):
    path = tmp_path / "d.exr"
    path.write_bytes(damage(exr_bytes(rgb)))
    with pytest.raises(InputError, match=message):
        read_exr(path)


def test_a_file_cut_short_anywhere_is_named_never_a_raw_error(tmp_path, rgb):
    """A render cut short (a full disk, a killed writer) at any byte: one InputError (a review:
    cut inside a header field or the offset table, struct's and numpy's own errors came out)."""
    whole = exr_bytes(rgb)
    path = tmp_path / "cut.exr"
    for size in range(len(whole)):
        path.write_bytes(whole[:size])
        with pytest.raises(InputError, match="OpenEXR"):
            read_exr(path)


def test_compressed_and_tiled_files_are_refused_by_name(tmp_path, rgb):
    path = tmp_path / "z.exr"
    path.write_bytes(exr_bytes(rgb, compression=3))
    with pytest.raises(InputError, match="compression 3"):
        read_exr(path)
    path.write_bytes(exr_bytes(rgb, flags=2 | 0x200))
    with pytest.raises(InputError, match="tiled"):
        read_exr(path)
    path.write_bytes(exr_bytes({"Y": rgb["R"]}))
    with pytest.raises(InputError, match="no channel 'R'"):
        read_exr(path)
