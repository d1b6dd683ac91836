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
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import OpenEXR

from rig.core.values import Window
from rig.physics.geometry import BrdfAngles


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
    """Write channel `Y` (cd/m², uncompressed: module docstring). Scalar float attributes are stored as 32-bit
    in EXR, so the exact metadata also goes in as one JSON string attribute `rig_metadata`."""
    # OpenEXR writes non-contiguous arrays scrambled without error (upstream #1929).
    pixels = np.ascontiguousarray(luminance_cd_m2, dtype=np.float32)
    header: dict[str, Any] = {"compression": OpenEXR.NO_COMPRESSION, "type": OpenEXR.scanlineimage,
                              "rig_metadata": json.dumps(dict(metadata), default=float)}
    for key, value in metadata.items():
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            header[key] = float(value)
        elif isinstance(value, str):
            header[key] = value
    OpenEXR.File(header, {"Y": pixels}).write(str(path))


def read_luminance_exr(path: str | Path) -> tuple[np.ndarray, dict[str, Any]]:
    """(luminance image, metadata) of a file written by write_luminance_exr."""
    exr = OpenEXR.File(str(path))
    meta = json.loads(exr.header().get("rig_metadata", "{}"))
    return np.array(exr.channels()["Y"].pixels, dtype=np.float32), meta
