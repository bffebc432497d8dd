"""PNG writer/reader: round trips, clamping, orientation, filters, corrupt files."""

import struct
import zlib

import numpy as np
import pytest

from bsplab import png


@pytest.mark.parametrize("channels", [3, 4])
def test_round_trip_is_exact_after_quantization(tmp_path, channels):
    rng = np.random.default_rng(1)
    image = rng.random((17, 23, channels)).astype(np.float32)
    path = tmp_path / "img.png"
    png.write_png(path, image)
    back = png.read_png(path)
    assert back.shape == (17, 23, channels) and back.dtype == np.uint8
    np.testing.assert_array_equal(back, np.rint(image * 255).astype(np.uint8))


def test_values_are_clamped_and_nan_is_black(tmp_path):
    image = np.array([[[-1.0, 0.5, 2.0], [np.nan, np.inf, -np.inf]]])
    png.write_png(tmp_path / "c.png", image)
    np.testing.assert_array_equal(png.read_png(tmp_path / "c.png"),
                                  [[[0, 128, 255], [0, 255, 0]]])


def test_row_zero_is_the_top_of_the_file(tmp_path):
    image = np.zeros((4, 3, 3))
    image[0, :, 0] = 1.0  # top row red
    path = tmp_path / "top.png"
    png.write_png(path, image)
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", data[16:24])
    assert (width, height) == (3, 4)
    # The first decoded scanline (filter byte + RGB triples) is the red row.
    idat = data[data.index(b"IDAT") + 4:]
    raw = zlib.decompressobj().decompress(idat)
    assert raw[:10] == bytes([0] + [255, 0, 0] * 3)
    assert png.read_png(path)[0, 0].tolist() == [255, 0, 0]


@pytest.mark.parametrize("shape", [(4, 4), (4, 4, 2), (4, 4, 5), (0, 4, 3)])
def test_bad_shapes_are_rejected(tmp_path, shape):
    with pytest.raises(ValueError):
        png.write_png(tmp_path / "bad.png", np.zeros(shape))


def _filtered_png(pixels: np.ndarray) -> bytes:
    """Encode with a different filter on each row (0..4), as other encoders do."""
    h, w, c = pixels.shape
    stride = w * c
    prev = np.zeros(stride, dtype=np.int64)
    out = bytearray()
    for y in range(h):
        kind = y % 5
        cur = pixels[y].reshape(-1).astype(np.int64)
        enc = []
        for i in range(stride):
            a = cur[i - c] if i >= c else 0
            b = prev[i]
            d = prev[i - c] if i >= c else 0
            p = a + b - d
            paeth = a if abs(p - a) <= min(abs(p - b), abs(p - d)) else (b if abs(p - b) <= abs(p - d) else d)
            pred = [0, a, b, (a + b) // 2, paeth][kind]
            enc.append((cur[i] - pred) % 256)
        out += bytes([kind] + enc)
        prev = cur

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data))

    ihdr = struct.pack(">IIBBBBB", w, h, 8, 6 if c == 4 else 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(bytes(out)))
            + chunk(b"IEND", b""))


def test_reader_undoes_all_five_row_filters(tmp_path):
    pixels = np.random.default_rng(2).integers(0, 256, (10, 7, 4), dtype=np.uint8)
    path = tmp_path / "f.png"
    path.write_bytes(_filtered_png(pixels))
    np.testing.assert_array_equal(png.read_png(path), pixels)


def test_corrupt_files_raise_value_error(tmp_path):
    good = tmp_path / "g.png"
    png.write_png(good, np.ones((2, 2, 3)))
    data = good.read_bytes()
    cases = {
        "sig.png": b"GIF89a" + data[6:],
        "crc.png": data[:30] + bytes([data[30] ^ 0xFF]) + data[31:],
        "short.png": data[:40],
    }
    for name, blob in cases.items():
        (tmp_path / name).write_bytes(blob)
        with pytest.raises(ValueError, match=name):
            png.read_png(tmp_path / name)
    with pytest.raises(FileNotFoundError):
        png.read_png(tmp_path / "missing.png")
