"""Luminance images as written by rig.data.images, read back by the OpenEXR library (the real consumer)."""

import numpy as np
import OpenEXR
import pytest

from rig.data.images import read_luminance_exr, write_luminance_exr

METADATA = {"point_id": "03-017", "theta_i_deg": 60.000000123, "phi_i_deg": 0.0, "exposures_s": [0.002, 0.008],
            "roi_window": [660, 485, 70, 70]}


def test_pixels_and_metadata_come_back_exactly(tmp_path):
    image = np.random.default_rng(1).lognormal(3.0, 2.0, (37, 53)).astype(np.float32)
    image[0, 0], image[1, 2] = 0.0, np.inf
    write_luminance_exr(tmp_path / "a.exr", image, METADATA)
    pixels, metadata = read_luminance_exr(tmp_path / "a.exr")
    np.testing.assert_array_equal(pixels, image)
    assert metadata == METADATA


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
