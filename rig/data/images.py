"""HDR luminance images as single-channel float32 OpenEXR files (docs/dataset.md, Images)."""

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
    """Write channel `Y` (cd/m²). Scalar float attributes are stored as 32-bit in EXR, so the
    exact metadata also goes in as one JSON string attribute `rig_metadata`."""
    # OpenEXR writes non-contiguous arrays scrambled without error (upstream #1929).
    pixels = np.ascontiguousarray(luminance_cd_m2, dtype=np.float32)
    header: dict[str, Any] = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage,
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
