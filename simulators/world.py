"""The simulated world: what is physically true on the simulated rig.

Simulated devices read and change this shared state: the axes set the true
motor angles, the lamp sets the light output, the meter and the camera observe
them. Nothing here knows about protocols.
"""

from __future__ import annotations

import math
from typing import Callable, Mapping

import numpy as np

from rig.brdf_models import BrdfModel
from rig.geometry import AXIS_NAMES
from rig.rigconfig import RigConfig
from simulators.clock import SimClock


class LampPhysics:
    """Halogen lamp on a constant-current supply: light ∝ I^p, warm-up and ageing drift."""

    def __init__(self, clock: SimClock, nominal_current_a: float, exponent: float,
                 warmup_amplitude: float, warmup_tau_s: float, drift_per_hour: float):
        self.clock = clock
        self.nominal_current_a = nominal_current_a
        self.exponent = exponent
        self.warmup_amplitude = warmup_amplitude
        self.warmup_tau_s = warmup_tau_s
        self.drift_per_hour = drift_per_hour
        self.output_on = False
        self._on_since = 0.0
        self._ramp = (0.0, 0.0, 0.0, 0.0)   # (t0, t1, i0, i1)

    def set_current(self, current_a: float, ramp_s: float) -> None:
        now = self.clock.now()
        self._ramp = (now, now + ramp_s, self.current_a(now), current_a)

    def current_setpoint_a(self) -> float:
        return self._ramp[3]

    def current_a(self, t: float | None = None) -> float:
        t = self.clock.now() if t is None else t
        t0, t1, i0, i1 = self._ramp
        if t >= t1 or t1 <= t0:
            return i1
        return i0 + (i1 - i0) * max(t - t0, 0.0) / (t1 - t0)

    def switch(self, on: bool) -> None:
        if on and not self.output_on:
            self._on_since = self.clock.now()
        self.output_on = on

    def relative_output(self, t: float | None = None) -> float:
        """Light output relative to a warm lamp at nominal current."""
        t = self.clock.now() if t is None else t
        if not self.output_on:
            return 0.0
        age = max(t - self._on_since, 0.0)
        warm = 1.0 + self.warmup_amplitude * math.exp(-age / self.warmup_tau_s)
        drift = 1.0 + self.drift_per_hour * age / 3600.0
        return (self.current_a(t) / self.nominal_current_a) ** self.exponent * warm * drift


class SimWorld:
    """Shared truth of one simulated rig."""

    def __init__(self, config: RigConfig, brdf: BrdfModel, brdf_params: Mapping[str, float],
                 clock: SimClock | None = None):
        self.config = config
        self.clock = clock or SimClock()
        self.rng = np.random.default_rng(config.simulation.seed)
        self.brdf_model = brdf
        self.brdf_params = dict(brdf_params)
        #: True-position getters registered by the simulated axes (0 when absent).
        self.axis_truth: dict[str, Callable[[], float]] = {}
        sim = config.simulation
        self.lamp = LampPhysics(self.clock, config.lamp.current_a, sim.lamp_exponent,
                                sim.warmup_amplitude, sim.warmup_tau_s, sim.drift_per_hour)

    def brdf(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """Ground-truth f_r (sr⁻¹) for SCS unit vectors."""
        return self.brdf_model(wi, wo, self.brdf_params)

    def illuminance_normal_lx(self, t: float | None = None) -> float:
        """True E⊥ on the sample plane at time t (now if None)."""
        return self.config.simulation.illuminance_normal_lx * self.lamp.relative_output(t)

    def motor_angles_deg(self) -> tuple[float, float, float, float]:
        """True axis positions (stage_vertical, stage_normal, arm_azimuth, arm_polar)."""
        return tuple(self.axis_truth[n]() if n in self.axis_truth else 0.0 for n in AXIS_NAMES)
