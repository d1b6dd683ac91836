"""HDR luminance images as single-channel float32 OpenEXR files (docs/dataset.md, Images).

Stored uncompressed: lossless is required of a measurement image, and of OpenEXR's lossless codecs the
ones that shrink a merged full frame cost more than the rest of a point. Measured on simulated quick-campaign
images (1390×1040 float32, OpenEXR 3.5, one core of a 2-core AMD EPYC; best of 3, write / size): none 12 ms
/ 100.3 %, RLE 43 ms / 100.2 %, PIZ 83 ms / 41 %, ZIPS 157 ms / 40 %, ZIP 167 ms / 33 %, ZSTD (≥ 3.4)
~1.5× ZIP's time / 50 %, HTJ2K 141 ms / 100 %; PXR24 and DWAA are lossy, B44 leaves float32 as is. ZIP's
third comes from the unlit part of the frame (a few distinct dark levels); the lit part, shot noise in
every mantissa, does not compress. rig.acquisition.diskspace bounds the file's size.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import OpenEXR

from rig.core.jsonfile import parse_json
from rig.core.values import Window
from rig.physics.geometry import BrdfAngles

#: OpenEXR's magic number, and the version field of a single-part scanline file (2), with the flag for
#: attribute names longer than EXR_SHORT_NAME_BYTES.
EXR_MAGIC = bytes([0x76, 0x2F, 0x31, 0x01])
EXR_VERSION = 2
EXR_LONG_NAMES = 0x400
EXR_SHORT_NAME_BYTES = 31
#: Codes of the header's values used: pixel type FLOAT, compression NONE, line order INCREASING_Y.
EXR_FLOAT = 2
EXR_NO_COMPRESSION = 0
EXR_INCREASING_Y = 0
#: Bytes of chunks laid out per write: well inside a core's L2 cache (256 KiB and more on current CPUs).
EXR_BLOCK_BYTES = 128 * 1024


def point_image_metadata(point_id: str, angles: BrdfAngles, exposures_s: Sequence[float],
                         roi_window: Window) -> dict[str, Any]:
    """What a point's image carries besides its pixels: the point, its achieved angles (degrees), the
    exposures merged (s) and where the ROI is (x0, y0, width, height in pixels), so an image can be
    matched to its brdf.csv row and its ROI found again without the dataset."""
    return {"point_id": point_id, "theta_i_deg": float(angles.theta_i_deg), "phi_i_deg": float(angles.phi_i_deg),
            "theta_o_deg": float(angles.theta_o_deg), "phi_o_deg": float(angles.phi_o_deg),
            "exposures_s": list(exposures_s),
            "roi_window": [roi_window.x0, roi_window.y0, roi_window.width, roi_window.height]}


def write_luminance_exr(path: str | Path, luminance_cd_m2: np.ndarray, metadata: Mapping[str, Any]) -> None:
    """Write channel `Y` (cd/m², float32, uncompressed: module docstring). Scalar float attributes are stored as
    32-bit in EXR, so the exact metadata also goes in as one JSON string attribute `rig_metadata`.

    The file is laid out here (openexr.com, "OpenEXR File Layout"): a single-part scanline file is a header of
    typed attributes, a table of the chunks' offsets and, uncompressed, one chunk per row (its row number,
    byte count and little-endian pixels). The OpenEXR library takes 1.5× as long for the same bytes (4.8
    against 3.3 ms for a 1390×1040 frame to tmpfs, best of 15), and a point with images saved is otherwise
    ~50 ms; the library still reads every file (read_luminance_exr, and the tests).
    """
    pixels = np.asarray(luminance_cd_m2, dtype="<f4")
    if pixels.ndim != 2 or 0 in pixels.shape:
        raise ValueError(f"a luminance image is a non-empty 2-D array, not one of shape {pixels.shape}")
    height, width = pixels.shape
    attributes = {"rig_metadata": ("string", json.dumps(dict(metadata), default=float).encode())}
    for key, value in metadata.items():
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            attributes[key] = ("float", struct.pack("<f", value))
        elif isinstance(value, str):
            attributes[key] = ("string", value.encode())
    window = struct.pack("<4i", 0, 0, width - 1, height - 1)
    attributes |= {
        "channels": ("chlist", b"Y\0" + struct.pack("<iB3xii", EXR_FLOAT, 0, 1, 1) + b"\0"),
        "compression": ("compression", bytes([EXR_NO_COMPRESSION])), "dataWindow": ("box2i", window),
        "displayWindow": ("box2i", window), "lineOrder": ("lineOrder", bytes([EXR_INCREASING_Y])),
        "pixelAspectRatio": ("float", struct.pack("<f", 1.0)), "screenWindowCenter": ("v2f", bytes(8)),
        "screenWindowWidth": ("float", struct.pack("<f", 1.0))}
    long_names = any(len(name) > EXR_SHORT_NAME_BYTES for name in attributes)
    header = b"".join([EXR_MAGIC, struct.pack("<i", EXR_VERSION | (EXR_LONG_NAMES if long_names else 0)),
                       *(name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value
                         for name, (kind, value) in sorted(attributes.items())), b"\0"])
    row_bytes = 8 + 4 * width
    offsets = len(header) + 8 * height + row_bytes * np.arange(height, dtype="<u8")
    # The chunks go out a block of rows at a time, laid out in a buffer that stays in the CPU's cache: a
    # whole-image buffer would be a fresh allocation (page faults) copied once more from main memory.
    rows = max(1, EXR_BLOCK_BYTES // row_bytes)
    chunks = np.empty((min(rows, height), 2 + width), "<i4")   # per row: y, byte count, pixels
    chunks[:, 1] = 4 * width
    with open(path, "wb") as file:
        file.write(header)
        file.write(offsets.data)
        for y0 in range(0, height, rows):
            block = chunks[:min(rows, height - y0)]
            block[:, 0] = np.arange(y0, y0 + len(block))
            block[:, 2:] = pixels[y0:y0 + len(block)].view("<i4")
            file.write(block.data)


def read_luminance_exr(path: str | Path) -> tuple[np.ndarray, dict[str, Any]]:
    """(luminance image, metadata) of a file written by write_luminance_exr."""
    exr = OpenEXR.File(str(path))
    meta = parse_json(exr.header().get("rig_metadata", "{}"), f"{path} (rig_metadata)")
    return np.array(exr.channels()["Y"].pixels, dtype=np.float32), meta
