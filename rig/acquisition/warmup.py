"""The lamp's warm-up: on, ramped to its current, and waited for until E⊥ is steady (campaign `lamp`)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rig.config.campaign import Lamp
from rig.config.rigfile import RigConfig
from rig.drivers.interfaces import RigDevices


def warm_up(cfg: Lamp, rig: RigConfig, dev: RigDevices, wait: Callable[[float], None],
            rig_time: Callable[[], float], event: Callable[..., Any], report: Callable[[str], None]) -> float:
    """Switch the lamp on and wait at least `warmup_min_s`, then until two meter readings `warmup_check_s`
    apart differ by less than `warmup_stable_rel` (or `warmup_max_s` has passed: event
    `warmup_not_stable`). Returns the lamp voltage once warm, the lamp suspender's reference."""
    lamp = dev.lamp
    lamp.set_current(0.0)
    lamp.set_output(True)
    lamp.set_current(rig.lamp.current_a, ramp_s=rig.lamp.ramp_s)
    start = rig_time()
    event("lamp_on", current_a=lamp.measure_current_a(), voltage_v=lamp.measure_voltage_v())
    report("lamp warm-up")
    wait(cfg.warmup_min_s)
    previous = dev.meter.read().illuminance_lx
    while True:
        wait(cfg.warmup_check_s)
        now = dev.meter.read().illuminance_lx
        change = abs(now - previous) / max(abs(now), 1e-300)
        elapsed = rig_time() - start
        if change < cfg.warmup_stable_rel or elapsed >= cfg.warmup_max_s:
            break
        previous = now
    voltage_v = lamp.measure_voltage_v()
    event("warmup_stable" if change < cfg.warmup_stable_rel else "warmup_not_stable",
          illuminance_lx=now, change_rel=change, warmup_s=elapsed, lamp_voltage_v=voltage_v)
    return voltage_v
