"""Single images: every format round-trips bit-exact (JPEG against Pillow's decoder), values as floats, sRGB."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import OpenEXR
import pytest
from PIL import Image

from facecap.cameras import image_to_float, linear_to_srgb, read_image, srgb_to_linear, write_image
from facecap.errors import FileFormatError, InputError

RNG = np.random.default_rng(3)


@pytest.mark.parametrize(
    ("suffix", "image"),
    [
        (".png", RNG.integers(0, 256, (17, 23, 3), dtype=np.uint8)),
        (".png", RNG.integers(0, 65536, (17, 23, 3), dtype=np.uint16)),
        (".png", RNG.integers(0, 65536, (17, 23), dtype=np.uint16)),
        (".png", RNG.integers(0, 256, (17, 23, 4), dtype=np.uint8)),
        (".tif", RNG.integers(0, 65536, (17, 23, 3), dtype=np.uint16)),
        (".exr", RNG.random((17, 23, 3), dtype=np.float32) * 40 - 5),
        (".exr", RNG.random((17, 23), dtype=np.float32)),
        (".exr", RNG.random((17, 23, 4), dtype=np.float32)),
    ],
    ids=["png8-rgb", "png16-rgb", "png16-grey", "png8-rgba", "tif16", "exr-rgb", "exr-grey", "exr-rgba"],
)
def test_lossless_formats_round_trip_bit_exact(tmp_path: Path, suffix: str, image: np.ndarray) -> None:
    write_image(tmp_path / f"a{suffix}", image)
    back = read_image(tmp_path / f"a{suffix}")
    assert back.dtype == image.dtype
    np.testing.assert_array_equal(back, image)
    assert [p.name for p in tmp_path.iterdir()] == [f"a{suffix}"]


def test_channel_order_is_rgb_as_pillow_reads_it(tmp_path: Path) -> None:
    image = np.zeros((4, 5, 3), dtype=np.uint8)
    image[..., 0] = 200  # red
    write_image(tmp_path / "red.png", image)
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "red.png")), image)
    Image.fromarray(image).save(tmp_path / "pil.png")
    np.testing.assert_array_equal(read_image(tmp_path / "pil.png"), image)


def test_jpeg_reads_as_pillow_decodes_it(tmp_path: Path) -> None:
    u, v = np.meshgrid(np.arange(64), np.arange(48))
    image = np.stack([u * 4, v * 5, (u + v) * 2], axis=-1).astype(np.uint8)
    write_image(tmp_path / "a.jpg", image)
    ours = read_image(tmp_path / "a.jpg").astype(int)
    pillow = np.asarray(Image.open(tmp_path / "a.jpg").convert("RGB")).astype(int)
    assert np.abs(ours - pillow).max() <= 2  # two libjpeg IDCTs
    assert np.abs(ours - image).mean() < 2.0  # quality 95


def test_exr_written_by_openexr_directly_is_read(tmp_path: Path) -> None:
    pixels = RNG.random((6, 7, 3), dtype=np.float32)
    header = {"compression": OpenEXR.PIZ_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"RGB": pixels}) as exr:
        exr.write(str(tmp_path / "ref.exr"))
    np.testing.assert_array_equal(read_image(tmp_path / "ref.exr"), pixels)


def test_half_float_exr_reads_as_float32_exactly(tmp_path: Path) -> None:
    pixels = (RNG.random((6, 7, 3)) * 10).astype(np.float16)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"RGB": pixels}) as exr:
        exr.write(str(tmp_path / "half.exr"))
    image = read_image(tmp_path / "half.exr")
    assert image.dtype == np.float32
    np.testing.assert_array_equal(image, pixels.astype(np.float32))


def test_image_to_float_and_srgb() -> None:
    np.testing.assert_array_equal(image_to_float(np.array([0, 255], np.uint8)), [0.0, 1.0])
    np.testing.assert_array_equal(image_to_float(np.array([0, 65535], np.uint16)), [0.0, 1.0])
    assert image_to_float(np.array([0.25], np.float64)).dtype == np.float32
    with pytest.raises(InputError, match="uint8, uint16 or float"):
        image_to_float(np.array([1], np.int32))
    # IEC 61966-2-1 reference points: sRGB 0.5 is linear 0.2140; the curve joins at 0.04045
    np.testing.assert_allclose(srgb_to_linear(np.array([0.0, 0.04045, 0.5, 1.0])),
                               [0.0, 0.04045 / 12.92, 0.21404114, 1.0], rtol=1e-6)
    x = np.linspace(0, 1, 1001)
    np.testing.assert_allclose(linear_to_srgb(srgb_to_linear(x)), x, atol=2e-6)


def test_srgb_matches_the_standard_and_keeps_a_computations_precision() -> None:
    # IEC 61966-2-1: 0.5 linear encodes to 0.735357; 0.0031308 sits at the knee (12.92 x)
    np.testing.assert_allclose(linear_to_srgb(np.array([0.0, 0.0031308, 0.18, 0.5, 1.0])),
                               [0.0, 0.04044994, 0.46135612, 0.73535698, 1.0], atol=1e-7)
    x = np.linspace(0, 1, 1001)
    assert srgb_to_linear(x).dtype == np.float64 and linear_to_srgb(x).dtype == np.float64
    np.testing.assert_allclose(srgb_to_linear(linear_to_srgb(x)), x, atol=1e-12)  # float64 in, float64 through
    assert srgb_to_linear(x.astype(np.float32)).dtype == np.float32
    assert srgb_to_linear(np.array([0, 255], np.uint8)).dtype == np.float32


def test_bad_images(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="EXR holds floats"):
        write_image(tmp_path / "a.exr", np.zeros((4, 4), np.uint8))
    with pytest.raises(InputError, match="uint8 or uint16"):
        write_image(tmp_path / "a.png", np.zeros((4, 4), np.float32))
    with pytest.raises(InputError, match="expected an"):
        write_image(tmp_path / "a.png", np.zeros((4, 4, 2), np.uint8))
    with pytest.raises(InputError, match="expected one of"):
        write_image(tmp_path / "a.bmp", np.zeros((4, 4), np.uint8))
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "broken.png").write_bytes(b"\x89PNG\r\n\x1a\n truncated")
    with pytest.raises(FileFormatError, match="cannot decode"):
        read_image(tmp_path / "broken.png")
    (tmp_path / "broken.exr").write_bytes(b"not an exr")
    with pytest.raises(FileFormatError, match="EXR"):
        read_image(tmp_path / "broken.exr")
    with pytest.raises(FileFormatError, match="not found"):
        read_image(tmp_path / "none.png")
