"""Single images: every format round-trips bit-exact (JPEG against Pillow's decoder), bad files named."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import OpenEXR
import pytest
from PIL import Image

from facecap.cameras import read_image, write_image
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


def test_bmp_round_trips(tmp_path: Path) -> None:
    image = np.random.default_rng(4).integers(0, 256, (5, 7, 3)).astype(np.uint8)
    write_image(tmp_path / "a.bmp", image)
    assert np.array_equal(read_image(tmp_path / "a.bmp"), image)


def test_bad_images(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="EXR holds floats"):
        write_image(tmp_path / "a.exr", np.zeros((4, 4), np.uint8))
    with pytest.raises(InputError, match="uint8 or uint16"):
        write_image(tmp_path / "a.png", np.zeros((4, 4), np.float32))
    with pytest.raises(InputError, match="expected an"):
        write_image(tmp_path / "a.png", np.zeros((4, 4, 2), np.uint8))
    with pytest.raises(InputError, match="expected one of"):
        write_image(tmp_path / "a.gif", np.zeros((4, 4), np.uint8))
    with pytest.raises(InputError, match="holds uint8"):
        write_image(tmp_path / "a.bmp", np.zeros((4, 4), np.uint16))  # BMP has no 16-bit colour
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "broken.png").write_bytes(b"\x89PNG\r\n\x1a\n truncated")
    with pytest.raises(FileFormatError, match="cannot decode"):
        read_image(tmp_path / "broken.png")
    (tmp_path / "broken.exr").write_bytes(b"not an exr")
    with pytest.raises(FileFormatError, match="EXR"):
        read_image(tmp_path / "broken.exr")
    with pytest.raises(FileFormatError, match="not found"):
        read_image(tmp_path / "none.png")
