"""The sRGB transfer curve at known values, and robust image loading."""

import numpy as np
import pytest
from PIL import Image

from renderer.color import linear_to_srgb, srgb_to_linear, to_uint8
from renderer.errors import InputError
from renderer.io import load_image, save_json, save_png


def test_srgb_curve_known_values():
    # IEC 61966-2-1: sRGB 0.5 is linear ((0.5 + 0.055) / 1.055) ** 2.4 = 0.21404
    assert abs(float(srgb_to_linear(0.5)) - 0.214041) < 1e-6
    assert abs(float(srgb_to_linear(0.04)) - 0.04 / 12.92) < 1e-12
    x = np.linspace(0, 1, 101)
    assert np.abs(linear_to_srgb(srgb_to_linear(x)) - x).max() < 1e-12
    single = linear_to_srgb(srgb_to_linear(x).astype(np.float32))  # float32 stays float32, 1e-6 from float64
    assert single.dtype == np.float32 and np.abs(single - x).max() < 1e-6
    assert float(linear_to_srgb(np.float32(0.214041))) == pytest.approx(0.5, abs=1e-6)


def test_float32_conversion_follows_the_curve_everywhere():
    # float32 is converted from a table of the curve (renderer/color.py): every float32 value of a dense sweep, the
    # knee's neighbours and the values just below 1 must lie within 2e-7 of the curve in float64, and never above 1.
    sweep = np.concatenate([np.linspace(0.0, 1.0, 3_000_001, dtype=np.float32),
                            np.nextafter(np.float32(0.0031308), np.float32([-1, 2])),
                            np.float32(1.0) - np.arange(200, dtype=np.float32) * np.finfo(np.float32).epsneg])
    c = sweep.astype(np.float64)
    curve = np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)
    single = linear_to_srgb(sweep)
    assert single.dtype == np.float32
    assert np.abs(single - curve).max() < 2e-7
    assert single.max() <= 1.0 and np.all(np.diff(single[:3_000_001]) >= 0.0)  # and it never goes down


def test_conversion_never_returns_nan():
    for dtype in (np.float64, np.float32):
        out = linear_to_srgb(np.array([np.nan, np.inf, -np.inf, -1.0, 2.0], dtype=dtype))
        assert np.all(np.isfinite(out)) and out.min() >= 0 and out.max() <= 1
        # The voxel shader relies on it: no rounding pushes a value just under or at 1 above 1.
        assert linear_to_srgb(np.linspace(0.999, 1.0, 1001, dtype=dtype)).max() <= 1.0
    assert list(to_uint8(np.array([0.0, 0.5, 1.0, np.nan]))) == [0, 128, 255, 0]


@pytest.mark.parametrize("mode", ["L", "P", "RGBA", "I;16", "LA", "RGB"])
def test_every_image_mode_loads_as_rgb(tmp_path, mode):
    rgb = np.zeros((10, 12, 3), np.uint8)
    rgb[:, :6] = (200, 100, 50)
    im = Image.fromarray(rgb)
    if mode == "I;16":
        im = Image.fromarray(np.asarray(im.convert("L")).astype(np.uint16) * 257)
    else:
        im = im.convert(mode)
    im.save(tmp_path / "a.png")
    image, alpha = load_image(tmp_path / "a.png")
    assert image.shape == (10, 12, 3) and image.dtype == np.float32
    assert np.isfinite(image).all() and image.min() >= 0 and image.max() <= 1
    assert (alpha is not None) == (mode in ("RGBA", "LA"))
    assert image[0, 0].mean() > image[0, 11].mean()  # left half bright, right half black


def test_exif_rotation_is_applied(tmp_path):
    im = Image.new("RGB", (20, 10), (255, 0, 0))
    exif = im.getexif()
    exif[0x0112] = 6  # rotate 90 degrees clockwise on display
    im.save(tmp_path / "r.jpg", exif=exif)
    image, _ = load_image(tmp_path / "r.jpg")
    assert image.shape[:2] == (20, 10)


def test_huge_images_are_downscaled(tmp_path):
    Image.new("RGB", (6000, 300), (0, 255, 0)).save(tmp_path / "wide.png")
    image, _ = load_image(tmp_path / "wide.png", max_side=1000)
    assert image.shape == (50, 1000, 3)


def test_unreadable_image_is_one_line(tmp_path):
    (tmp_path / "bad.png").write_bytes(b"not a png at all")
    with pytest.raises(InputError) as err:
        load_image(tmp_path / "bad.png")
    assert "bad.png" in str(err.value) and "\n" not in str(err.value)


def test_failed_write_leaves_no_temporary_file_and_keeps_the_old_one(tmp_path):
    target = tmp_path / "keep.json"
    save_json(target, {"a": 1})
    with pytest.raises(ValueError):
        save_json(target, {"a": float("nan")})  # JSON cannot hold NaN: nothing may be written
    assert target.read_text().strip().startswith("{") and '"a": 1' in target.read_text()
    assert [p.name for p in tmp_path.iterdir()] == ["keep.json"]
    save_png(tmp_path / "x.png", np.zeros((4, 4, 3)))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.json", "x.png"]
