"""How much disk a dataset will take, and whether its folder has that much free, before a run starts.

A run that fills the disk ends as a clean failure (DatasetWriter turns ENOSPC into
DiskFullError), but it is better not to start one: `rig run` and `--resume` refuse
(exit 2) when the estimate below exceeds the free space.

The per-item sizes are upper bounds measured on simulated campaigns (brdf.csv rows
with full-precision floats ~490 bytes; events.jsonl ~1.1 kB per point, mostly the
`point_pending` record that repeats the row, plus E⊥ readings and retries), then
multiplied by TEXT_SAFETY for what a long run on hardware adds (pauses, retries).
Images are float32 full frames in uncompressed EXR (rig.data.images says why): the pixels, a
16-byte offset-table entry and chunk header per row, and the header (point id, angles and the
JSON metadata, well under EXR_HEADER_BYTES) make an exact bound.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from rig.config.rigfile import RigConfig
from rig.data.output_folder import RESERVE_BYTES, existing_parent, format_bytes

ROW_BYTES = 600
EVENT_BYTES_PER_POINT = 1400
SKIPPED_ROW_BYTES = 120
#: dataset.json (campaign and rig config inside, ~10 kB), its temp copy, the run's fixed events.
FIXED_BYTES = 64 * 1024
TEXT_SAFETY = 1.5
EXR_HEADER_BYTES = 4096
BYTES_PER_PIXEL = 4          # float32 luminance
#: Per image row: its 8-byte entry in the offset table and its chunk's 8-byte header (row number, byte
#: count); uncompressed, every chunk is one row (openexr.com, "OpenEXR File Layout").
EXR_BYTES_PER_ROW = 16


def image_bytes(rig: RigConfig) -> int:
    """One full-frame luminance image of the rig's camera, as written by rig.data.images."""
    cam = rig.camera
    return cam.height_px * (cam.width_px * BYTES_PER_PIXEL + EXR_BYTES_PER_ROW) + EXR_HEADER_BYTES


def estimate_dataset_bytes(n_points: int, n_skipped: int, rig: RigConfig, save_images: bool) -> int:
    """Bytes the dataset folder will take for `n_points` more points (and `n_skipped` skipped ones)."""
    text = n_points * (ROW_BYTES + EVENT_BYTES_PER_POINT) + n_skipped * SKIPPED_ROW_BYTES + FIXED_BYTES
    images = n_points * image_bytes(rig) if save_images else 0
    return int(text * TEXT_SAFETY) + images + RESERVE_BYTES


def free_bytes(folder: Path) -> int:
    """Free space where `folder` is, or will be created (its nearest existing parent)."""
    return shutil.disk_usage(existing_parent(folder)).free


def space_problem(folder: Path, needed: int, remedy: str = "free some space or choose another --out") -> str | None:
    """A one-line refusal naming the folder, the space needed and the space free; None if it fits."""
    try:
        free = free_bytes(folder)
    except OSError:
        return None          # cannot tell (e.g. a permission error): the writer will say what is wrong
    if free >= needed:
        return None
    return (f"{folder}: not enough free disk space for the dataset: about {format_bytes(needed)} needed, "
            f"{format_bytes(free)} free; {remedy} (nothing was written)")
