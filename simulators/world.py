"""The simulated world: what is physically true on the simulated rig.

Simulated devices read and change this shared state: the axes set the true
motor angles, the lamp sets the light output, the meter and the camera observe
them. Nothing here knows about protocols.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from contextlib import AbstractContextManager, nullcontext

import numpy as np

from rig.config.rigfile import RigConfig
from rig.core.clock import Clock
from rig.physics.brdf_models import BrdfModel
from rig.physics.geometry import AXIS_NAMES, sample_frame
from rig.physics.goniometer_fit import rotation_from_vector
from rig.planning.points import as_motors
from rig.simulators.clock import ServedClock, SimClock
from rig.simulators.lamp import LampPhysics


class SimWorld:
    """Shared truth of one simulated rig."""

    def __init__(self, config: RigConfig, brdf: BrdfModel, brdf_params: Mapping[str, float],
                 clock: Clock | None = None):
        """`clock`: a SimClock (the in-process simulated rig, the default) or a ServedClock, a wall clock that runs
        `--speed` times faster and stands still while the world computes (a served rig, `rig sim serve`)."""
        self.config = config
        self.clock = clock or SimClock()
        self.rng = np.random.default_rng(config.simulation.seed)
        self.brdf_model = brdf
        self.brdf_params = dict(brdf_params)
        #: True-position getters registered by the simulated axes (0 when absent).
        self.axis_truth: dict[str, Callable[[], float]] = {}
        #: Each simulated axis's zero error (physical minus encoder angle, deg), registered with it.
        self.axis_zero_deg: dict[str, float] = {}
        sim = config.simulation
        self.lamp = LampPhysics(self.clock, config.lamp.current_a, sim.lamp_exponent,
                                sim.warmup_amplitude, sim.warmup_tau_s, sim.drift_per_hour)
        #: True transmission of each filter-wheel position: the certificate's value off by an error drawn
        #: once per run within its stated uncertainty (an rng of its own, so that a rig with a wheel draws
        #: every other truth as one without).
        filters = config.attenuator.filters if config.attenuator else []
        errors = np.random.default_rng([sim.seed, 1288]).standard_normal(len(filters))
        self.transmission_truth = {f.position: f.transmission * (1.0 + f.u_rel * e) for f, e in zip(filters, errors)}
        #: The filter-wheel position in the beam, registered by the simulated wheel (None: no wheel).
        self.filter_position: Callable[[], int] | None = None
        #: The camera's mount on the arm (a rotation applied after camera_frame: pointing x, y, roll) and the
        #: sample holder's tilt (applied after sample_frame), drawn once per run from an rng of their own, so that
        #: drawing them leaves every other truth as it was: what `rig calibrate geometry` must find.
        mount, tilt = np.random.default_rng([sim.seed, 36]).standard_normal((2, 3))
        #: The same as angles (deg): pointing x, y and roll; tilt about the sample x and y.
        self.camera_mount_deg = mount * sim.camera_mount_sigma_deg
        self.holder_tilt_deg = tilt[:2] * sim.holder_tilt_sigma_deg
        self.camera_mount = rotation_from_vector(np.radians(self.camera_mount_deg))
        self.holder_tilt = rotation_from_vector(np.radians([*self.holder_tilt_deg, 0.0]))

    def spend_s(self, seconds: float) -> None:
        """Let `seconds` of rig time pass inside an instrument (a meter integrating, a camera exposing),
        from a peer's thread: a SimClock is advanced without running the client's keep-alives or stop
        check (the client is blocked waiting for the reply); a wall clock is simply waited on."""
        if isinstance(self.clock, SimClock):
            self.clock.advance(seconds)
        else:
            self.clock.sleep(seconds)

    def computing(self) -> AbstractContextManager[None]:
        """Where the world computes (a frame rendered), which costs no rig time: a served world's clock stands
        still meanwhile (ServedClock); a SimClock only moves when slept on anyway."""
        return self.clock.computing() if isinstance(self.clock, ServedClock) else nullcontext()

    def brdf(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """Ground-truth f_r (sr⁻¹) for SCS unit vectors."""
        return self.brdf_model(wi, wo, self.brdf_params)

    def illuminance_normal_lx(self, t: float | None = None) -> float:
        """True E⊥ on the sample plane at time t (now if None)."""
        return self.config.simulation.illuminance_normal_lx * self.lamp.relative_output(t)

    def transmission(self) -> float:
        """True transmission of what is in front of the camera now (1: no wheel, or a position without a
        calibrated filter, i.e. an open one)."""
        return 1.0 if self.filter_position is None else self.transmission_truth.get(self.filter_position(), 1.0)

    def holder_frame(self) -> np.ndarray:
        """Columns: the sample x, y and normal in the GCS at the true stage angles, the holder's tilt included."""
        alpha, beta = np.radians(self.motor_angles_deg()[:2])
        return sample_frame(alpha, beta) @ self.holder_tilt

    def motor_angles_deg(self) -> tuple[float, float, float, float]:
        """True axis positions (stage_vertical, stage_normal, arm_azimuth, arm_polar)."""
        return as_motors(self.axis_truth[n]() if n in self.axis_truth else 0.0 for n in AXIS_NAMES)
