"""Suspenders, stop requests and how a run ended, each on its own (no rig)."""

import pytest

from rig.acquisition.ledger import Mark
from rig.acquisition.outcome import ending_of
from rig.acquisition.stopping import AbortRequested, StopRequested, StopRequests
from rig.acquisition.suspenders import DeviceSilent, IlluminanceJump, LampOutOfTolerance, install
from rig.config.campaign import Lamp as WarmUp
from rig.config.campaign import Suspenders, parse_campaign
from rig.config.rigfile import RigConfig
from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.core.values import IlluminanceReading
from rig.drivers.interfaces import IlluminanceMeter, LampSupply
from rig.physics.illuminance import IlluminanceEstimate


class Lamp(LampSupply):
    def __init__(self, current_a: float, voltage_v: float):
        self.current_a, self.voltage_v = current_a, voltage_v

    def identity(self) -> str:
        return "lamp"

    def set_current(self, current_a: float, ramp_s: float = 0.0) -> None:
        self.current_a = current_a

    def set_output(self, on: bool) -> None:
        pass

    def output_is_on(self) -> bool:
        return True

    def measure_current_a(self) -> float:
        return self.current_a

    def measure_voltage_v(self) -> float:
        return self.voltage_v


class Meter(IlluminanceMeter):
    def __init__(self, *values_lx: float):
        self.values_lx = list(values_lx)

    def identity(self) -> str:
        return "meter"

    def read(self) -> IlluminanceReading:
        return IlluminanceReading(self.values_lx.pop(0), 1e-6, 1e9)


class StepClock(Clock):
    def __init__(self) -> None:
        self.t = 0.0
        self.sleeps: list[float] = []

    def now(self) -> float:
        return self.t

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.t += seconds


def lamp_suspender(lamp: Lamp, reference_v: float | None = 12.0, clock: Clock | None = None,
                   marks: list | None = None) -> LampOutOfTolerance:
    tolerances = Suspenders(lamp_current_tolerance_rel=0.02, lamp_voltage_tolerance_rel=0.05)
    return LampOutOfTolerance(lamp, 4.0, tolerances, lambda: reference_v, clock or StepClock(),
                              mark=(marks if marks is not None else []).append)


def test_lamp_suspender_names_a_burn_out_a_drifting_current_and_voltage():
    assert lamp_suspender(Lamp(4.0, 12.0)).check() is None
    assert "burnt out" in lamp_suspender(Lamp(0.0, 0.1)).check()
    drifting = lamp_suspender(Lamp(3.8, 12.0)).check()
    assert drifting.startswith("lamp current 3.800 A") and "burnt out" not in drifting
    assert lamp_suspender(Lamp(4.0, 13.0)).check() == "lamp voltage 13.000 V, 12.000 V after warm-up"
    assert lamp_suspender(Lamp(4.0, 13.0), reference_v=None).check() is None      # before the first warm-up
    s = lamp_suspender(Lamp(4.0, 12.0))
    assert (s.rewind_to, s.rewarm) == (Mark.LAMP_CHECKED, True)
    for _ in range(10):
        s.discarded(["s0-p1"])           # no limit: a lamp fault is the lamp's, not the point's
    assert s.discards["s0-p1"] == 10


def test_illuminance_jump_trips_beyond_the_limit_and_clears_once_steady():
    waited: list[float] = []
    steady = WarmUp(warmup_check_s=60.0, warmup_stable_rel=0.002)
    jump = IlluminanceJump(Meter(1000.0, 1050.0, 1000.0, 1000.5), 0.02, steady, 0.002, waited.append)
    before = IlluminanceEstimate(1000.0, 1.0, 0.0, 5, 0.0)
    assert jump.jump(None, before) is None
    assert jump.jump(before, IlluminanceEstimate(1015.0, 1.0, 0.0, 5, 9.0)) is None
    assert jump.jump(before, IlluminanceEstimate(1030.0, 1.0, 0.0, 5, 9.0)) == \
        "E⊥ 1030.0 lx, 1000.0 lx at the previous reading"
    assert jump.check() == "E⊥ still changing: 1000.0 → 1050.0 lx" and waited == [60.0]
    assert jump.check() is None
    assert jump.rewind_to is Mark.READING
    for _ in range(jump.max_retakes):
        jump.discarded(["s0-p1", "s0-p2"])
    with pytest.raises(DeviceError, match="point s0-p1 discarded 4 times") as failed:
        jump.discarded(["s0-p1"])
    assert "illuminance_drift_limit_rel = 0.02 (last change 0.03" in str(failed.value)


def test_a_silent_device_is_probed_until_it_answers():
    answers = [DeviceError("meter", "no reply", unanswered=True), None]

    def probe() -> None:
        answer = answers.pop(0)
        if answer is not None:
            raise answer
    silent = DeviceSilent("meter", probe)
    assert silent.check() == "meter: no reply"
    assert silent.check() is None
    assert (silent.name, silent.rewind_to, silent.rewarm) == ("meter", None, False)


def test_waits_honour_a_stop_within_a_check_interval_and_log_it_once():
    clock, honoured = StepClock(), []
    requests = StopRequests(clock, honoured.append)
    requests.wait(2.5)
    assert clock.sleeps == [1.0, 1.0, 0.5]
    requests.request_stop("Ctrl+C")
    requests.request_stop("again")
    for _ in range(2):
        with pytest.raises(StopRequested):
            requests.wait(10.0)
    assert honoured == ["Ctrl+C"] and clock.sleeps == [1.0, 1.0, 0.5]
    requests.request_abort("SIGTERM")
    with pytest.raises(AbortRequested):
        requests.check_abort()
    assert requests.reason == "SIGTERM"


def test_one_place_decides_how_a_run_ended():
    assert ending_of(None).status == "complete"
    stopped = ending_of(StopRequested("Ctrl+C"))
    assert (stopped.status, stopped.graceful) == ("interrupted", True)
    for abort in (AbortRequested("SIGTERM"), KeyboardInterrupt()):
        ending = ending_of(abort)
        assert (ending.status, ending.graceful, ending.error) == ("interrupted", False, None)
    failed = ending_of(DeviceError("lamp", "alarm"))
    assert (failed.status, failed.error, failed.message) == ("failed", "DeviceError: lamp: alarm", "lamp: alarm")
    assert (ending_of(SystemExit(3)).status, ending_of(SystemExit(3)).error) == ("failed", None)


def test_the_lamp_is_checked_on_a_schedule_and_each_passing_check_marks_the_ledger():
    """Polled before every point, the lamp is queried at most every CHECK_EVERY_S of rig time; each passing check
    marks the ledger (Mark.LAMP_CHECKED), a failing one does not (what a trip takes back: test_ledger)."""
    clock, lamp, marks = StepClock(), Lamp(4.0, 12.0), []
    queries = []
    lamp.measure_current_a = lambda: queries.append("I") or lamp.current_a
    s = lamp_suspender(lamp, clock=clock, marks=marks)
    for _ in range(3):                   # three points a second apart: one check, before the first
        assert s.poll() is None
        clock.sleep(1.0)
    assert queries == ["I"] and marks == [Mark.LAMP_CHECKED]
    lamp.current_a = 0.0                 # burnt out during the third point
    assert s.poll() is None and queries == ["I"]            # not due yet
    clock.sleep(s.CHECK_EVERY_S)
    assert "burnt out" in s.poll() and marks == [Mark.LAMP_CHECKED]     # due: a trip, no mark
    lamp.current_a = 4.0
    assert s.check() is None and marks == [Mark.LAMP_CHECKED] * 2
    assert s.poll() is None and len(queries) == 3           # checked just now: not due


def test_rows_appended_at_once_keep_the_lamp_checked_before_every_point():
    """With `illuminance.correction: latest` no point waits to be taken back: no schedule."""
    class Devices:
        lamp, meter, clock = Lamp(4.0, 12.0), Meter(), StepClock()
    base = {"name": "t", "sample": {"id": "S"}, "incidence": [{"phi": 0, "theta": [0]}],
            "viewing": [{"centred_on": "normal", "theta": [10], "phi": [0]}]}
    every_s = {}
    for correction in ("interpolate", "latest"):
        campaign = parse_campaign({**base, "illuminance": {"correction": correction}})
        installed = install(campaign, RigConfig(), Devices(), lamp_reference_v=lambda: 12.0, wait=lambda s: None,
                            mark=lambda mark: None)
        every_s[correction] = installed.polled[0].check_every_s
    assert every_s == {"interpolate": LampOutOfTolerance.CHECK_EVERY_S, "latest": 0.0}
