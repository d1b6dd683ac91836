"""The lamp warm-up a run will need, for `rig plan` and the run's first ETA (the moves are rig.planning.plan's).

The warm-up ends at the first check whose two meter readings, `warmup_check_s` apart, differ by less than
`warmup_stable_rel` (rig.acquisition.warmup). How long that takes depends on the lamp, and where the criterion
is close to the meter's noise, on chance: the minimum alone (`warmup_min_s`) says too little. An estimate says
where it comes from (`source`), which `rig plan` prints:
- the last runs' warm-ups on the same rig (their median), when some are known;
- else the rig file's lamp model: on the simulated rig its `simulation` section (warm-up amplitude and time
  constant, meter noise), through the warm-up rule (`model_warmup_s`); rig.session.warmup_estimate replays the
  simulated rig itself, seed included, which is exact;
- else, for a real lamp with no history, the least the rule allows (the minimum and one check), stated as such.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rig.config.campaign import Lamp
from rig.config.rigfile import RigConfig, SimulationConfig

#: Nominal capture time per point for plan estimates (`rig plan`, the ETA): probe, one main
#: exposure, readouts. The ETA corrects it by the rig time the points actually take.
NOMINAL_CAPTURE_S = 0.05
#: Simulated warm-ups averaged by `model_warmup_s` (a fixed seed: the estimate is deterministic).
MODEL_TRIALS = 2000
#: Past warm-ups whose median stands for the next one.
HISTORY_RUNS = 5


@dataclass(frozen=True)
class WarmupEstimate:
    """Expected warm-up (s, from the lamp's ramp to E⊥ stable) and where that number comes from."""
    seconds: float
    source: str

    def as_record(self) -> dict[str, float | str]:
        return {"seconds": self.seconds, "source": self.source}


def checks_end(lamp: Lamp, seconds: float) -> float:
    """`seconds` rounded up to when the rule can end a warm-up: the minimum, then every check, at most the
    maximum's check."""
    checks = max(math.ceil((seconds - lamp.warmup_min_s) / lamp.warmup_check_s - 1e-9), 1)
    end = lamp.warmup_min_s + checks * lamp.warmup_check_s
    return min(end, lamp.warmup_min_s + math.ceil((lamp.warmup_max_s - lamp.warmup_min_s) / lamp.warmup_check_s)
               * lamp.warmup_check_s)


def model_warmup_s(lamp: Lamp, sim: SimulationConfig, ramp_s: float) -> float:
    """Mean warm-up of a lamp whose output is 1 + amplitude·exp(−age/τ) (age from switch-on, `ramp_s` before
    the warm-up starts), read by a meter with relative noise `meter_noise_rel`, under the campaign's rule."""
    rng = np.random.default_rng(0)
    ended = np.full(MODEL_TRIALS, np.nan)

    def reading(elapsed: float) -> np.ndarray:
        output = 1.0 + sim.warmup_amplitude * math.exp(-(elapsed + ramp_s) / sim.warmup_tau_s)
        return output * (1.0 + rng.normal(0.0, sim.meter_noise_rel, MODEL_TRIALS))

    elapsed = lamp.warmup_min_s
    previous = reading(elapsed)
    while True:
        elapsed += lamp.warmup_check_s
        now = reading(elapsed)
        stop = np.isnan(ended) & ((np.abs(now - previous) / np.abs(now) < lamp.warmup_stable_rel)
                                  | (elapsed >= lamp.warmup_max_s))
        ended[stop] = elapsed
        if not np.isnan(ended).any():
            return float(np.mean(ended))
        previous = now


def warmup_estimate(lamp: Lamp, rig: RigConfig, past_s: Sequence[float] = (), past_where: str = "") -> WarmupEstimate:
    """The warm-up to expect: the median of the last HISTORY_RUNS `past_s` (oldest first) found `past_where`,
    else the rig's lamp model (the simulated rig's), else the least the campaign's rule allows."""
    if past_s:
        last = list(past_s)[-HISTORY_RUNS:]
        return WarmupEstimate(checks_end(lamp, statistics.median(last)),
                              f"the median of the last {len(last)} warm-up{'s' if len(last) > 1 else ''} of rig "
                              f"{rig.name}{past_where}")
    if rig.simulated:
        sim = rig.simulation
        return WarmupEstimate(model_warmup_s(lamp, sim, rig.lamp.ramp_s),
                              f"the simulated lamp's model (output {sim.warmup_amplitude:+.1%} at switch-on, "
                              f"τ {sim.warmup_tau_s:g} s, meter noise {sim.meter_noise_rel:.2%}), averaged")
    return WarmupEstimate(lamp.warmup_min_s + lamp.warmup_check_s,
                          f"at least: the campaign's minimum and one check; no earlier warm-up of rig {rig.name} "
                          f"known{past_where}")
