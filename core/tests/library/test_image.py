"""bsplab.image: PNG round trips, quantization, orientation, clear errors."""

import numpy as np
import pytest

from bsplab import image

PIL = pytest.importorskip("PIL.Image")


@pytest.mark.parametrize("channels", [3, 4])
def test_round_trip_is_exact_after_quantization(tmp_path, channels):
    rng = np.random.default_rng(1)
    picture = rng.random((17, 23, channels)).astype(np.float32)
    path = tmp_path / "img.png"
    image.write_png(path, picture)
    back = image.read_png(path)
    assert back.shape == (17, 23, channels) and back.dtype == np.uint8
    np.testing.assert_array_equal(back, np.rint(picture * 255).astype(np.uint8))


@pytest.mark.parametrize("channels", [3, 4])
def test_uint8_is_written_unchanged(tmp_path, channels):
    pixels = np.random.default_rng(2).integers(0, 256, (5, 9, channels), dtype=np.uint8)
    image.write_png(tmp_path / "u.png", pixels)
    np.testing.assert_array_equal(image.read_png(tmp_path / "u.png"), pixels)


def test_values_are_clamped_and_nan_is_black(tmp_path):
    picture = np.array([[[-1.0, 0.5, 2.0], [np.nan, np.inf, -np.inf]]])
    np.testing.assert_array_equal(image.to_uint8(picture), [[[0, 128, 255], [0, 255, 0]]])
    image.write_png(tmp_path / "c.png", picture)
    np.testing.assert_array_equal(image.read_png(tmp_path / "c.png"),
                                  [[[0, 128, 255], [0, 255, 0]]])


def test_row_zero_is_the_top_of_the_file(tmp_path):
    picture = np.zeros((4, 3, 3))
    picture[0, :, 0] = 1.0  # top row red
    path = tmp_path / "top.png"
    image.write_png(path, picture)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with PIL.open(path) as im:  # read by Pillow directly, not through our reader
        assert im.size == (3, 4) and im.mode == "RGB"
        assert im.getpixel((0, 0)) == (255, 0, 0) and im.getpixel((0, 1)) == (0, 0, 0)


def test_reader_expands_grey_and_palette_files(tmp_path):
    grey = np.arange(12, dtype=np.uint8).reshape(3, 4) * 20
    PIL.fromarray(grey, "L").save(tmp_path / "grey.png")
    np.testing.assert_array_equal(image.read_png(tmp_path / "grey.png"),
                                  np.repeat(grey[:, :, None], 3, axis=2))


@pytest.mark.parametrize("shape", [(4, 4), (4, 4, 2), (4, 4, 5), (0, 4, 3)])
def test_bad_shapes_are_rejected(tmp_path, shape):
    with pytest.raises(ValueError, match=r"expected an \(H, W, 3\|4\) image"):
        image.write_png(tmp_path / "bad.png", np.zeros(shape))


def test_bad_types_are_rejected(tmp_path):
    with pytest.raises(TypeError, match="float or uint8 image, got int64"):
        image.write_png(tmp_path / "bad.png", np.zeros((2, 2, 3), dtype=np.int64))


def test_corrupt_files_raise_value_error(tmp_path):
    good = tmp_path / "g.png"
    image.write_png(good, np.ones((2, 2, 3)))
    data = good.read_bytes()
    cases = {
        "sig.png": b"GIF89a" + data[6:],
        "short.png": data[:40],
        "empty.png": b"",
    }
    for name, blob in cases.items():
        (tmp_path / name).write_bytes(blob)
        with pytest.raises(ValueError, match=f"{name}: not a readable PNG image"):
            image.read_png(tmp_path / name)
    with pytest.raises(FileNotFoundError, match="missing.png: no such file"):
        image.read_png(tmp_path / "missing.png")
