"""What every capture path offers the engine: a `Capturer` that takes a point, and the `PointAcquisition` it
returns.

Apart from the choice of path (rig.acquisition.capturer) so that the paths, and the filter wheel that wraps one
(rig.acquisition.attenuation), implement the same interface without importing the module that chooses them.
"""

from __future__ import annotations

from typing import Protocol

from rig.core.values import PointCapture, SensorInfo, Window


class PointAcquisition(Protocol):
    """What one point took from the camera, before its numbers are computed."""

    @property
    def clipped(self) -> bool:
        """Whether ROI pixels saturated in every exposure (their luminance is only a lower bound)."""

    def reduce(self) -> PointCapture:
        """The point's ROI statistics, flags and uncertainty components (and its image when saved)."""


class Capturer(Protocol):
    """Takes the points of a run with one camera, the same way each time."""

    @property
    def sensor(self) -> SensorInfo: ...

    @property
    def roi(self) -> Window:
        """The central ROI whose luminance is the point's measurement."""

    def acquire(self) -> PointAcquisition:
        """Expose the current view as its ROI needs."""

    def probe(self, exposure_s: float) -> tuple[float, float]:
        """One exposure of the ROI alone: its peak as a fraction of the usable range, and the exposure realised."""
