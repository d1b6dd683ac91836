"""In-process simulated axes, lamp supply and illuminance meter on a SimWorld.

They implement the driver interfaces directly; the protocol peers of issue 3
will sit between these models and the real drivers.
"""

from __future__ import annotations

from drivers.interfaces import Axis, DeviceError, IlluminanceMeter, IlluminanceReading, LampSupply
from rig.rigconfig import AxisConfig
from rig.motion import move_time_s, position_at
from simulators.world import SimWorld


class SimAxis(Axis):
    """Rotation axis with a trapezoidal profile, soft limits, repeatability and an encoder."""

    def __init__(self, world: SimWorld, name: str, cfg: AxisConfig):
        self.world = world
        self.name = name
        self.cfg = cfg
        self._start = (0.0, 0.0, 0.0)   # (t0, from_deg, to_deg); to_deg includes positioning error
        self._end_s = 0.0
        world.axis_truth[name] = self._true_position

    def _true_position(self) -> float:
        t0, frm, to = self._start
        elapsed = self.world.clock.now() - t0
        return position_at(frm, to, elapsed, self.cfg.speed_deg_s, self.cfg.accel_deg_s2)

    def start_move(self, target_deg: float) -> None:
        lo, hi = self.cfg.limits_deg
        if not lo <= target_deg <= hi:
            raise DeviceError(self.name, f"target {target_deg:.4f}° outside soft limits [{lo}, {hi}]°")
        now = self.world.clock.now()
        here = self._true_position()
        sigma = self.world.config.simulation.positioning_sigma_deg
        landing = target_deg + (self.world.rng.normal(0.0, sigma) if sigma else 0.0)
        self._start = (now, here, landing)
        self._end_s = now + self.move_time_s(here, landing)

    def wait(self, timeout_s: float | None = None) -> None:
        remaining = self._end_s - self.world.clock.now()
        if timeout_s is not None and remaining > timeout_s:
            self.world.clock.sleep(timeout_s)
            raise DeviceError(self.name, f"move not finished after {timeout_s:.1f} s")
        if remaining > 0:
            self.world.clock.sleep(remaining)

    def position_deg(self) -> float:
        res = self.world.config.simulation.encoder_resolution_deg
        return round(self._true_position() / res) * res

    def is_moving(self) -> bool:
        return self.world.clock.now() < self._end_s

    def stop(self) -> None:
        here = self._true_position()
        self._start = (self.world.clock.now(), here, here)
        self._end_s = self.world.clock.now()

    def home(self) -> None:
        self.start_move(0.0)
        self.wait()

    def move_time_s(self, start_deg: float, target_deg: float) -> float:
        return move_time_s(target_deg - start_deg, self.cfg.speed_deg_s, self.cfg.accel_deg_s2) + self.cfg.settle_s

    def identity(self) -> str:
        return f"sim-axis {self.name}"


class SimLampSupply(LampSupply):
    """Constant-current supply driving the simulated halogen lamp."""

    def __init__(self, world: SimWorld, filament_hot_ohm: float = 2.9):
        self.world = world
        self.filament_hot_ohm = filament_hot_ohm

    def identity(self) -> str:
        return "sim Delta Elektronika SM1500 (rig sim)"

    def set_current(self, current_a: float, ramp_s: float = 0.0) -> None:
        if current_a < 0:
            raise DeviceError("lamp", f"negative current {current_a} A refused")
        self.world.lamp.set_current(current_a, ramp_s)
        if ramp_s > 0:
            self.world.clock.sleep(ramp_s)

    def set_output(self, on: bool) -> None:
        self.world.lamp.switch(on)

    def output_is_on(self) -> bool:
        return self.world.lamp.output_on

    def measure_current_a(self) -> float:
        return self.world.lamp.current_a() if self.world.lamp.output_on else 0.0

    def measure_voltage_v(self) -> float:
        return self.measure_current_a() * self.filament_hot_ohm


class SimIlluminanceMeter(IlluminanceMeter):
    """Optometer head at the sample plane: photocurrent ∝ E⊥ with relative noise."""

    def __init__(self, world: SimWorld):
        self.world = world
        self.cal = world.config.meter.calibration_lx_per_a

    def identity(self) -> str:
        return "sim Gigahertz-Optik P9710 (rig sim)"

    def read(self) -> IlluminanceReading:
        t_int = self.world.config.meter.integration_s
        e_true = self.world.illuminance_normal_lx(self.world.clock.now() + t_int / 2)
        self.world.clock.sleep(t_int)
        noise = self.world.config.simulation.meter_noise_rel
        e = e_true * (1.0 + self.world.rng.normal(0.0, noise)) if noise else e_true
        photocurrent = e / self.cal
        return IlluminanceReading(photocurrent * self.cal, photocurrent, self.cal)
