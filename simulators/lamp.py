"""Halogen lamp on a DC supply: filament resistance with thermal lag, light output, burn-out.

Pure physics on a clock, no I/O: the supply peer programs it (current, voltage
limit, output) and reads back voltage and current; the camera and the meter
read its light output.
"""

from __future__ import annotations

import math

from rig.core.clock import Clock

#: Integration steps per thermal time constant (exponential Euler; exact at constant current).
STEPS_PER_TAU = 10
#: Relative distance to the steady-state resistance at which the filament counts as settled.
SETTLED_REL = 1e-12


class LampPhysics:
    """Tungsten-halogen lamp fed by a current source with a voltage limit.

    * Filament: the steady-state resistance rises with the current, from
      R_cold = cold_ratio·R_hot with no current to R_hot = rated voltage / nominal
      current, as R_cold + (R_hot − R_cold)·(I/I_nom)^resistance_exponent; the
      actual resistance follows it with a first-order thermal lag, so a current
      step shows a voltage transient (and switching on cold is an inrush).
    * Supply: constant current at the programmed (linearly ramped) value unless
      I·R would exceed the voltage limit; then constant voltage, I = V_lim/R.
      The limit is infinite until a supply sets one.
    * Light ∝ (I/I_nom)^exponent × warm-up × ageing drift, both counted from
      switch-on. The sub-second filament lag is neglected for the light: the
      warm-up term models the slow part that matters to a measurement.
    * Burn-out opens the filament: no current, the supply sits at its voltage
      limit, no light; `replace()` installs a new, cold lamp.
    """

    def __init__(self, clock: Clock, nominal_current_a: float, exponent: float,
                 warmup_amplitude: float, warmup_tau_s: float, drift_per_hour: float, *,
                 rated_voltage_v: float = 12.0, cold_ratio: float = 0.1, resistance_exponent: float = 0.8,
                 thermal_tau_s: float = 0.15):
        self.clock = clock
        self.nominal_current_a = nominal_current_a
        self.exponent = exponent
        self.warmup_amplitude = warmup_amplitude
        self.warmup_tau_s = warmup_tau_s
        self.drift_per_hour = drift_per_hour
        self.hot_resistance_ohm = rated_voltage_v / nominal_current_a
        self.cold_resistance_ohm = cold_ratio * self.hot_resistance_ohm
        self.resistance_exponent = resistance_exponent
        self.thermal_tau_s = thermal_tau_s
        self.output_on = False
        self.burnt_out = False
        self.compliance_v = math.inf
        self._on_since = 0.0
        self._ramp = (0.0, 0.0, 0.0, 0.0)                          # (t0, t1, i0, i1)
        self._thermal = (clock.now(), self.cold_resistance_ohm)    # (t, R) at the last change
        #: (thermal state, ramp, t, R): from t on, with that state and ramp, the filament has settled at R
        self._settled: tuple[tuple[float, float], tuple[float, float, float, float], float, float] | None = None

    # -- what the supply does ----------------------------------------------------------------
    def set_current(self, current_a: float, ramp_s: float = 0.0) -> None:
        """Program the source current, reached linearly over `ramp_s`."""
        now = self._settle_history()
        self._ramp = (now, now + ramp_s, self.current_a(now), current_a)

    def set_compliance(self, voltage_v: float) -> None:
        """Voltage limit of the supply (its voltage setpoint in constant-current operation)."""
        self._settle_history()
        self.compliance_v = voltage_v

    def switch(self, on: bool) -> None:
        now = self._settle_history()
        if on and not self.output_on:
            self._on_since = now
        self.output_on = on

    # -- what happens to the lamp ------------------------------------------------------------
    def burn_out(self) -> None:
        """The filament opens."""
        self._settle_history()
        self.burnt_out = True

    def replace(self) -> None:
        """Install a new lamp: intact, cold, and warming up again from now if the output is on."""
        now = self.clock.now()
        self.burnt_out = False
        self._thermal = (now, self.cold_resistance_ohm)
        self._on_since = now

    # -- observables ---------------------------------------------------------------------------
    def current_setpoint_a(self) -> float:
        return self._ramp[3]

    def current_a(self, t: float | None = None) -> float:
        """Programmed source current at time t (the ramp included)."""
        t = self.clock.now() if t is None else t
        t0, t1, i0, i1 = self._ramp
        if t >= t1 or t1 <= t0:
            return i1
        return i0 + (i1 - i0) * max(t - t0, 0.0) / (t1 - t0)

    def steady_resistance_ohm(self, current_a: float) -> float:
        """Filament resistance after a long time at `current_a`."""
        rise = (abs(current_a) / self.nominal_current_a) ** self.resistance_exponent
        return self.cold_resistance_ohm + (self.hot_resistance_ohm - self.cold_resistance_ohm) * rise

    def resistance_ohm(self, t: float | None = None) -> float:
        """Filament resistance at time t ≥ the last change (earlier t gives the value at that change)."""
        t = self.clock.now() if t is None else t
        settled = self._settled
        if settled is not None and settled[0] is self._thermal and settled[1] is self._ramp and t >= settled[2]:
            return settled[3]                   # the integration below would end at the same settled value
        t_a, r = self._thermal
        steps = math.ceil(max(t - t_a, 0.0) * STEPS_PER_TAU / self.thermal_tau_s)
        if steps == 0:
            return r
        h = (t - t_a) / steps
        decay = math.exp(-h / self.thermal_tau_s)
        for k in range(steps):
            mid = t_a + (k + 0.5) * h
            r_ss = self.steady_resistance_ohm(self._through_filament(mid, r))
            r = r_ss + (r - r_ss) * decay
            if mid >= self._ramp[1] and abs(r - r_ss) <= SETTLED_REL * r_ss:
                self._settled = (self._thermal, self._ramp, mid, r_ss)
                return r_ss                     # constant drive and settled: nothing changes any more
        return r

    def filament_current_a(self, t: float | None = None) -> float:
        """Current actually flowing: 0 with the output off or the filament open."""
        t = self.clock.now() if t is None else t
        return self._through_filament(t, self.resistance_ohm(t))

    def voltage_v(self, t: float | None = None) -> float:
        """Voltage at the supply terminals: I·R, or the voltage limit across an open filament."""
        t = self.clock.now() if t is None else t
        if not self.output_on:
            return 0.0
        if self.burnt_out:
            return self.compliance_v
        return min(self.current_a(t) * self.resistance_ohm(t), self.compliance_v)

    def relative_output(self, t: float | None = None) -> float:
        """Light output relative to a warm lamp at nominal current."""
        t = self.clock.now() if t is None else t
        current = self.filament_current_a(t)
        if current == 0.0:
            return 0.0
        age = max(t - self._on_since, 0.0)
        warm = 1.0 + self.warmup_amplitude * math.exp(-age / self.warmup_tau_s)
        drift = 1.0 + self.drift_per_hour * age / 3600.0
        return (current / self.nominal_current_a) ** self.exponent * warm * drift

    # -- internals -----------------------------------------------------------------------------
    def _through_filament(self, t: float, resistance_ohm: float) -> float:
        if not self.output_on or self.burnt_out:
            return 0.0
        return min(self.current_a(t), self.compliance_v / resistance_ohm)

    def _settle_history(self) -> float:
        """Fix the filament state at now before the drive changes; returns now."""
        now = self.clock.now()
        self._thermal = (now, self.resistance_ohm(now))
        return now
