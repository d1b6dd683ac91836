"""Simulated luminance camera: renders the simulated world and reads it through the sensor model.

Each pixel of the requested window looks along its pinhole ray (rig.physics.optics);
where the ray hits the front of the sample inside the collimated lamp beam the
scene luminance is L = f_r(ωi, ωo) · E⊥ · cos θi · texture(x, y) · glint(x, y, ωi, ωo),
with ωo the per-pixel direction from that point to the camera; everywhere else it is the
configured ambient (stray-light) luminance. The lamp housing's occlusion of the
view and the camera's shadow are not modelled: the planner excludes those points.
Whatever is rendered passes through the sensor model (rig.simulators.sensor), which
applies the lens's cos⁴ fall-off, PRNU, DSNU and the optional nonlinearity.
"""

from __future__ import annotations

import numpy as np

from rig.config.rigfile import camera_optics
from rig.core.errors import DeviceError
from rig.core.values import Frame, Window
from rig.drivers.interfaces import LuminanceCamera
from rig.physics.geometry import LAMP_DIRECTION_GCS, sample_frame
from rig.physics.optics import faces_lamp, in_beam, intersect_sample_plane, pixel_rays
from rig.simulators.sensor import SensorModel
from rig.simulators.texture import GlintTexture, ValueNoiseTexture
from rig.simulators.world import SimWorld


class SimCamera(LuminanceCamera):
    """In-process peer of a calibrated luminance camera looking at a SimWorld."""

    def __init__(self, world: SimWorld):
        cfg = world.config
        self.world = world
        self.sensor = cfg.camera.sensor_info()
        self.optics = camera_optics(cfg)
        self.texture = ValueNoiseTexture.from_config(cfg.simulation)
        self.glint = GlintTexture.from_config(cfg.simulation)
        self.model = SensorModel.from_config(cfg.camera, cfg.simulation, world.rng)

    def identity(self) -> str:
        return "simulated LMK 98-4 (rig sim)"

    def luminance(self, window: Window, illuminance_normal_lx: float) -> np.ndarray:
        """Noise-free luminance (cd/m², (height, width)) reaching the sensor at the true (physical) motor
        angles: the scene's, through the filter-wheel filter in the beam (true transmission), if any."""
        cfg = self.world.config
        alpha, beta, a, b = np.radians(self.world.motor_angles_deg())
        origin, rays = pixel_rays(self.optics, a, b, window)
        frame = sample_frame(alpha, beta)
        lum = np.full((window.height, window.width), cfg.simulation.ambient_cd_m2)
        if not faces_lamp(frame[:, 2]):
            return lum * self.world.transmission()
        points = intersect_sample_plane(origin, rays, frame[:, 2])
        lit = in_beam(points, cfg.geometry.spot_diameter_m / 2)
        keep = lit.ravel()           # compress is 5× faster than boolean indexing of (h, w, 3)
        xy = points.reshape(-1, 3).compress(keep, axis=0) @ frame[:, :2]
        wo = rays.reshape(-1, 3).compress(keep, axis=0) @ -frame   # back along the ray, SCS
        wi = LAMP_DIRECTION_GCS @ frame
        lum[lit] = (self.world.brdf(wi, wo) * (illuminance_normal_lx * wi[2])
                    * self.texture(xy[:, 0], xy[:, 1]) * self.glint(xy[:, 0], xy[:, 1], wi, wo))
        return lum * self.world.transmission()         # through the filter in the beam, if any

    def capture(self, exposure_s: float, window: Window | None = None) -> Frame:
        return self._expose(exposure_s, window, dark=False)

    def capture_dark(self, exposure_s: float, window: Window | None = None) -> Frame:
        return self._expose(exposure_s, window, dark=True)

    def render(self, exposure_s: float, window: Window | None, dark: bool) -> tuple[Frame, float]:
        """Render the scene at mid-exposure and read it through the sensor, without letting time pass:
        the frame and the rig time its exposure + readout take (the caller spends it, so that a served
        camera's client can sleep it on its own clock while its keep-alives run)."""
        full = self.full_window()
        window = full if window is None else window
        try:
            full.inner(window)
        except ValueError as exc:
            raise DeviceError("camera", str(exc)) from None
        if not np.isfinite(exposure_s):
            raise DeviceError("camera", f"exposure time {exposure_s!r} s is not a number")
        t = float(np.clip(exposure_s, self.sensor.min_exposure_s, self.sensor.max_exposure_s))
        start = self.world.clock.now()
        lum = 0.0 if dark else self.luminance(window, self.world.illuminance_normal_lx(start + t / 2))
        pixels = self.model.read(self.world.rng, lum, t, window)
        fraction = (window.width * window.height) / (full.width * full.height)
        duration = t + self.world.config.camera.readout_s * fraction
        return Frame(pixels, t, window, dark=dark, meta={"start_s": start}), duration

    def _expose(self, exposure_s: float, window: Window | None, dark: bool) -> Frame:
        """Render, then spend exposure + readout time on the world's clock."""
        frame, duration = self.render(exposure_s, window, dark)
        self.world.clock.sleep(duration)
        return frame


class UniformSourceCamera(SimCamera):
    """The simulated camera looking into a uniform source (an integrating sphere's port filling the field
    of view) of luminance `luminance_cd_m2`: what `rig calibrate camera` measures on the simulated rig. The
    lens's vignetting and the sensor's PRNU, DSNU and nonlinearity still apply (SensorModel)."""

    def __init__(self, world: SimWorld, luminance_cd_m2: float):
        super().__init__(world)
        self.source_cd_m2 = luminance_cd_m2

    def identity(self) -> str:
        return "simulated camera before a uniform source (rig sim)"

    def luminance(self, window: Window, illuminance_normal_lx: float) -> np.ndarray:
        return np.full((window.height, window.width), self.source_cd_m2)
