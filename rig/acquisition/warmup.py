"""The lamp's warm-up: on, ramped to its current, and waited for until E⊥ is steady (campaign `lamp`).

A warm-up lasts minutes with nothing moving, so it says how it goes: the progress line every REPORT_EVERY_S
of rig time (elapsed, the expected rest, the last reading and its change), and for the monitor an event every
`warmup_check_s` (docs/dataset.md): `warmup_wait` during the minimum wait (no reading is taken then), then
`warmup_check` with each check's reading. The expected rest comes from the run's ETA (rig.acquisition.eta,
which holds the warm-up the run expects: rig.planning.estimate).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rig.acquisition.eta import Eta
from rig.config.campaign import Lamp
from rig.config.rigfile import RigConfig
from rig.core import events
from rig.drivers.interfaces import RigDevices

#: Rig time between two progress reports while the warm-up waits.
REPORT_EVERY_S = 10.0


@dataclass(frozen=True)
class WarmedUp:
    """How a warm-up ended: the lamp voltage once warm (the lamp suspender's reference), its length (s from
    the end of the current ramp), and whether E⊥ was stable (else `warmup_max_s` passed)."""
    lamp_voltage_v: float
    warmup_s: float
    stable: bool
    change_rel: float


def _clock(seconds: float) -> str:
    seconds = max(0, round(seconds))
    return f"{seconds // 60}:{seconds % 60:02d}"


class _Progress:
    """The warm-up's waits, cut into REPORT_EVERY_S slices that each report, and its expected rest."""

    def __init__(self, cfg: Lamp, wait: Callable[[float], None], rig_time: Callable[[], float],
                 report: Callable[[str], None], eta: Eta | None):
        self.cfg, self.wait_, self.rig_time, self.report, self.eta = cfg, wait, rig_time, report, eta
        self.start = rig_time()
        self.last = ""                       # the last reading's words

    def elapsed(self) -> float:
        return self.rig_time() - self.start

    def left_s(self, next_check: float) -> float:
        """The expected rest: to the expected end, and at least to the next check (the rule ends at a check)."""
        expected = self.eta.warmup_expected_s if self.eta is not None else 0.0
        return max(min(max(expected, next_check), self.cfg.warmup_max_s), next_check) - self.elapsed()

    def wait(self, seconds: float, next_check: float) -> None:
        end = self.elapsed() + seconds
        while (step := min(REPORT_EVERY_S, end - self.elapsed())) > 1e-9:
            self.say(next_check)
            self.wait_(step)
        self.say(next_check)

    def say(self, next_check: float) -> None:
        left = self.left_s(next_check)
        if self.eta is not None:
            self.eta.warming(left)
        self.report(f"lamp warm-up {_clock(self.elapsed())}, ≈ {_clock(left)} left{self.last}")


def warm_up(cfg: Lamp, rig: RigConfig, dev: RigDevices, wait: Callable[[float], None],
            rig_time: Callable[[], float], event: Callable[..., Any], report: Callable[[str], None],
            eta: Eta | None = None) -> WarmedUp:
    """Switch the lamp on and wait at least `warmup_min_s`, then until two meter readings `warmup_check_s`
    apart differ by less than `warmup_stable_rel` (or `warmup_max_s` has passed: event `warmup_not_stable`).
    `eta`: the run's, told the warm-up's expected rest as it goes (and 0 at its end)."""
    lamp = dev.lamp
    lamp.set_current(0.0)
    lamp.set_output(True)
    lamp.set_current(rig.lamp.current_a, ramp_s=rig.lamp.ramp_s)
    progress = _Progress(cfg, wait, rig_time, report, eta)
    event(events.LAMP_ON, current_a=lamp.measure_current_a(), voltage_v=lamp.measure_voltage_v())
    next_check = cfg.warmup_min_s + cfg.warmup_check_s
    while (rest := cfg.warmup_min_s - progress.elapsed()) > 1e-9:
        progress.wait(min(cfg.warmup_check_s, rest), next_check)
        if cfg.warmup_min_s - progress.elapsed() > 1e-9:
            event(events.WARMUP_WAIT, warmup_s=progress.elapsed(), expected_left_s=progress.left_s(next_check))
    previous = dev.meter.read().illuminance_lx
    while True:
        progress.wait(cfg.warmup_check_s, next_check)
        now = dev.meter.read().illuminance_lx
        change = abs(now - previous) / max(abs(now), 1e-300)
        elapsed = progress.elapsed()
        if change < cfg.warmup_stable_rel or elapsed >= cfg.warmup_max_s:
            break
        next_check = elapsed + cfg.warmup_check_s
        event(events.WARMUP_CHECK, illuminance_lx=now, change_rel=change, stable_rel=cfg.warmup_stable_rel,
              warmup_s=elapsed, expected_left_s=progress.left_s(next_check))
        progress.last = f": E⊥ {now:.5g} lx, changed {change:.2%} in {cfg.warmup_check_s:g} s " \
                        f"(steady below {cfg.warmup_stable_rel:.2%})"
        previous = now
    voltage_v = lamp.measure_voltage_v()
    event(events.WARMUP_STABLE if change < cfg.warmup_stable_rel else events.WARMUP_NOT_STABLE,
          illuminance_lx=now, change_rel=change, warmup_s=elapsed, lamp_voltage_v=voltage_v)
    if eta is not None:
        eta.warming(0.0)
    return WarmedUp(voltage_v, elapsed, change < cfg.warmup_stable_rel, change)
