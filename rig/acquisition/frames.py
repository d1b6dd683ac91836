"""Raw frames kept as stacks: a point's frames of one exposure (`FrameStack`) and the run's dark frames
(`DarkFrameCache`), reused from point to point on the 1/6-stop exposure ladder.

Only the raw path (rig.acquisition.capture) takes frames; a camera that calibrates its own pictures takes
its own darks.
"""

from __future__ import annotations

import numpy as np

from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.core.values import Frame, SensorInfo, Window
from rig.drivers.interfaces import LuminanceCamera


def pixels_of(camera: LuminanceCamera, frame: Frame, window: Window) -> np.ndarray:
    """`window`'s pixels of a frame; a camera that cannot read windows returns a larger one."""
    if frame.pixels_dn.shape != (frame.window.height, frame.window.width):
        raise DeviceError(camera.identity(), f"returned a {frame.pixels_dn.shape} frame for window {frame.window}")
    try:
        return frame.pixels_dn[frame.window.inner(window)]
    except ValueError:
        raise DeviceError(camera.identity(), f"returned window {frame.window} for window {window}") from None


class DarkFrameCache:
    """Dark frames keyed by (exposure time, window), taken when first needed.

    Dark signal depends on exposure time and sensor temperature, not on the
    scene, so one dark serves every point exposed on the same rung of the
    exposure ladder while it is valid: younger than the `max_age_s` asked for,
    on `clock` (the run's, which the capturer owning the cache hands it), and not
    dropped by `invalidate` (call it when the sensor temperature has changed).
    """

    def __init__(self, frames_per_dark: int = 1, steps_per_stop: int = 6, clock: Clock | None = None):
        if frames_per_dark < 1 or steps_per_stop < 1:
            raise ValueError("frames_per_dark and steps_per_stop must be ≥ 1")
        self.frames_per_dark = frames_per_dark
        self.steps_per_stop = steps_per_stop
        self.clock = clock
        self.n_taken = 0                  # dark frames taken so far
        self.exposed_s = 0.0              # their summed exposure time
        self._darks: dict[tuple[float, Window], tuple[float, FrameStack]] = {}

    def snap(self, exposure_s: float, sensor: SensorInfo) -> float:
        """Nearest exposure time (s) on the ladder, clamped to the sensor's range.

        Clamping before rounding too makes snap idempotent when a range limit is
        not a rung (the ladder then ends on the rung nearest the limit).
        """
        limits = sensor.min_exposure_s, sensor.max_exposure_s
        rung = np.round(np.log2(np.clip(exposure_s, *limits)) * self.steps_per_stop) / self.steps_per_stop
        return float(np.clip(2.0 ** rung, *limits))

    def get(self, camera: LuminanceCamera, exposure_s: float, window: Window, frames: int = 1,
            max_age_s: float | None = None) -> np.ndarray:
        """Stack (m, H, W), m ≥ max(frames_per_dark, frames), of raw darks for a ladder exposure.

        A stack taken more than `max_age_s` ago is re-taken; a short one is
        topped up and keeps the age of its first frame.
        """
        if exposure_s != self.snap(exposure_s, camera.sensor):
            raise ValueError(f"exposure {exposure_s} s is not on the dark-frame ladder; use snap()")
        if max_age_s is not None and self.clock is None:
            raise ValueError("dark frames can only age on a clock: give the DarkFrameCache the rig clock")
        now = self.clock.now() if self.clock else 0.0
        key = (exposure_s, window)
        taken_s, stack = self._darks.get(key, (now, FrameStack()))
        if max_age_s is not None and now - taken_s > max_age_s:
            taken_s, stack = now, FrameStack()
        while len(stack) < max(self.frames_per_dark, frames):
            frame = camera.capture_dark(exposure_s, window)
            stack.append(pixels_of(camera, frame, window))
            self.n_taken += 1
            self.exposed_s += frame.exposure_s
        self._darks[key] = (taken_s, stack)
        return stack.array()

    def invalidate(self) -> None:
        """Forget all darks, so that the next points take fresh ones."""
        self._darks.clear()

    def __len__(self) -> int:
        return len(self._darks)


class FrameStack:
    """Frames of one exposure, added one by one and read as one (n, H, W) array. The array is stacked once
    per count and shared by every reader (so read-only): a point reads its stacks several times, and a
    full frame's copy costs about as much as its merge."""

    def __init__(self) -> None:
        self._frames: list[np.ndarray] = []
        self._array: np.ndarray | None = None

    def append(self, frame: np.ndarray) -> None:
        self._frames.append(frame)
        self._array = None

    def __len__(self) -> int:
        return len(self._frames)

    def array(self) -> np.ndarray:
        if self._array is None:         # one frame, the usual count, is its own stack: a view, not a copy
            self._array = self._frames[0][np.newaxis] if len(self._frames) == 1 else np.stack(self._frames)
            self._array.flags.writeable = False
        return self._array
