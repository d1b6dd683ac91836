"""Luminance images as written by rig.data.images, read back by the OpenEXR library (the real consumer)."""

import numpy as np
import OpenEXR
import pytest

from rig.data.images import EXR_BLOCK_BYTES, read_luminance_exr, write_luminance_exr

METADATA = {"point_id": "03-017", "theta_i_deg": 60.000000123, "phi_i_deg": 0.0, "exposures_s": [0.002, 0.008],
            "roi_window": [660, 485, 70, 70]}


def test_pixels_and_metadata_come_back_exactly(tmp_path):
    image = np.random.default_rng(1).lognormal(3.0, 2.0, (37, 53)).astype(np.float32)
    image[0, 0], image[1, 2] = 0.0, np.inf
    write_luminance_exr(tmp_path / "a.exr", image, METADATA)
    pixels, metadata = read_luminance_exr(tmp_path / "a.exr")
    np.testing.assert_array_equal(pixels, image)
    assert metadata == METADATA


def test_an_image_written_in_several_blocks_of_rows_comes_back_exactly(tmp_path):
    """Rows wide enough that a write carries a few of them (EXR_BLOCK_BYTES), the last block a shorter one."""
    width = EXR_BLOCK_BYTES // (6 * 4)
    rows_per_block = EXR_BLOCK_BYTES // (8 + 4 * width)
    image = np.random.default_rng(2).random((3 * rows_per_block + 2, width), dtype=np.float32)
    write_luminance_exr(tmp_path / "a.exr", image, METADATA)
    np.testing.assert_array_equal(read_luminance_exr(tmp_path / "a.exr")[0], image)


def test_the_header_is_a_single_channel_uncompressed_float_scanline_image(tmp_path):
    write_luminance_exr(tmp_path / "a.exr", np.ones((4, 6)), METADATA)
    exr = OpenEXR.File(str(tmp_path / "a.exr"))
    header, channel = exr.header(), exr.channels()["Y"]
    assert list(exr.channels()) == ["Y"] and channel.pixels.dtype == np.float32
    assert header["compression"] == OpenEXR.NO_COMPRESSION and header["type"] == OpenEXR.scanlineimage
    for window in ("dataWindow", "displayWindow"):
        np.testing.assert_array_equal(np.concatenate(header[window]), [0, 0, 5, 3])
    assert header["point_id"] == "03-017"
    assert header["theta_i_deg"] == pytest.approx(60.0, rel=1e-7)          # a 32-bit float attribute


def test_long_attribute_names_and_any_array_layout_are_written(tmp_path):
    """Names over 31 bytes need the version field's long-names flag; a float64, transposed (non-contiguous)
    array is written as its float32 values in row order."""
    image = np.arange(12.0).reshape(3, 4).T
    write_luminance_exr(tmp_path / "a.exr", image, {"a_name_longer_than_thirty_one_bytes": "yes"})
    pixels, metadata = read_luminance_exr(tmp_path / "a.exr")
    np.testing.assert_array_equal(pixels, image.astype(np.float32))
    assert metadata == {"a_name_longer_than_thirty_one_bytes": "yes"}


@pytest.mark.parametrize("shape", [(3, 4, 2), (0, 5), (5,)])
def test_what_is_not_an_image_is_refused(tmp_path, shape):
    with pytest.raises(ValueError, match="non-empty 2-D"):
        write_luminance_exr(tmp_path / "a.exr", np.zeros(shape), {})
