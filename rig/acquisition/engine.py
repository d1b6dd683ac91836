"""The run engine: executes a plan on a set of devices and writes the dataset.

It owns the sequence (warm-up, E⊥ on a schedule, move → capture → process →
append) and the exits: whatever happens, the lamp is switched off, the axes are
stopped and the manifest says how the run ended. It does I/O and bookkeeping;
the physics it calls (kinematics, HDR merge, BRDF, uncertainty) is pure.

Drift correction needs the E⊥ reading *after* a point, so with
`illuminance.correction: interpolate` a measured point is first written ahead
to events.jsonl (`point_pending`, fsync'ed: nothing is lost if the process
dies) and appended to brdf.csv once the next reading brackets it.

Stopping. The operator's requests arrive as flags (`request_stop`, `request_abort`;
set from a signal handler or another thread, never doing I/O there). A graceful stop
is honoured by every wait of the engine, which sleeps in slices of at most
STOP_CHECK_S of rig time, and between points, never inside one: the point in flight
is finished, a closing E⊥ reading brackets the points waiting for one, the axes park.
An abort (stop the axes now) is honoured by any sleep of the clock, even inside a
move. Either way the exit path makes the rig safe first, and nothing can interrupt it.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from dataclasses import dataclass, replace
from typing import Callable, Sequence, TypeVar

import numpy as np

from rig.acquisition.capture import DarkFrameCache, PointCapture, acquire_point, reduce_point
from rig.config.campaign import Campaign
from rig.config.rigfile import RigConfig, camera_optics
from rig.core.errors import DeviceError
from rig.core.values import IlluminanceReading, Progress, ProgressCallback
from rig.data.dataset import DatasetWriter, utc_now
from rig.drivers.interfaces import RigDevices
from rig.physics import geometry as geo
from rig.physics.budget import BUDGET_COLUMNS, campaign_budget
from rig.physics.illuminance import IlluminanceEstimate, ReadingSchedule, estimate, interpolate
from rig.physics.optics import roi_inside_spot
from rig.physics.pipeline import brdf_from_luminance
from rig.planning.collisions import path_crosses, zones_of
from rig.planning.ordering import travel_time_s
from rig.planning.plan import move_time_s
from rig.planning.points import Plan, PlannedPoint

#: Nominal capture time per point for plan estimates (`rig plan`, the ETA): probe, one main
#: exposure, readouts. The ETA corrects it by the rig time the points actually take.
NOMINAL_CAPTURE_S = 0.05


T = TypeVar("T")


class CollisionError(RuntimeError):
    """A move would cross a forbidden zone of the rig configuration; nothing moved."""


class StopRequested(Exception):
    """A graceful stop (first Ctrl+C): raised by a wait of the engine or between points, never inside one."""


class AbortRequested(BaseException):
    """Stop the axes now (second Ctrl+C, SIGTERM): raised by any sleep of the rig clock or between points.

    A BaseException like KeyboardInterrupt, so that no `except Exception` on its way (a driver's
    retry, a suspender's probe) takes it for a device fault.
    """


@dataclass(frozen=True)
class Measurement:
    """Everything measured at one point, before E⊥ turns it into a BRDF row."""

    point: PlannedPoint
    motors_deg: tuple[float, float, float, float]
    angles: geo.BrdfAngles
    capture: PointCapture
    flags: tuple[str, ...]
    time_utc: str
    rig_time_s: float


class Runner:
    """Runs one campaign; `run()` returns the final status (complete/interrupted/failed)."""

    #: Moves may take this much longer than predicted before the axis counts as stuck.
    MOVE_TIMEOUT_FACTOR = 2.0
    MOVE_TIMEOUT_MARGIN_S = 10.0
    #: Lamp current below this fraction of the setpoint: the pause names a burn-out or an open circuit.
    LAMP_CURRENT_MIN_FRACTION = 0.5

    #: Where the axes go after a graceful stop (home).
    PARK_DEG = (0.0, 0.0, 0.0, 0.0)
    #: Longest rig time (s) between two looks at the stop request while the engine waits.
    STOP_CHECK_S = 1.0
    #: A point discarded for an E⊥ jump is re-taken at most this many times; one more jump
    #: fails the run (a drift limit the lamp and meter cannot meet would re-take for ever).
    MAX_RETAKES = 3

    def __init__(self, campaign: Campaign, plan: Plan, devices: RigDevices, writer: DatasetWriter,
                 rig: RigConfig, progress: ProgressCallback | None = None, done_rows: Sequence[dict] = ()):
        """`done_rows`: rows already in the dataset (a resume); their points are not measured again."""
        self.campaign = campaign
        self.plan = plan
        self.dev = devices
        self.writer = writer
        self.rig = rig
        self.progress = progress or (lambda p: None)
        self.settings = campaign.capture.settings()
        self.darks = DarkFrameCache(frames_per_dark=self.settings.frames_per_exposure, clock=devices.clock)
        self.optics = camera_optics(rig)
        ill = campaign.illuminance
        self.schedule = ReadingSchedule(ill.remeasure, ill.every)
        self.interpolate = ill.correction == "interpolate"
        self.t0 = devices.clock.now()
        self.rows: list[dict] = list(done_rows)     # written rows, for the campaign budget
        self.done_ids = {r["point_id"] for r in done_rows}
        self.measured = len(done_rows)
        self.stop_reason: str | None = None        # set by request_stop: finish the point, park
        self.abort_reason: str | None = None       # set by request_abort: stop the axes now
        self._stop_logged = False
        self.pending: list[Measurement] = []       # waiting for the next E⊥ reading
        self.reading: IlluminanceEstimate | None = None
        self._points_since_reading = 0
        self.lamp_ref_v: float | None = None       # lamp voltage when warm: the voltage suspender's reference
        self.moving_to: tuple[float, ...] | None = None   # target of a move started and not yet waited for
        self._discards: Counter[str] = Counter()   # E⊥-jump discards per point id
        # ETA: plan estimate per point, corrected by measured / estimated rig time of the points done
        self._estimate_s: dict[str, float] = {}
        self._left_estimate_s = self._done_estimate_s = 0.0
        self._active_s = 0.0                       # rig time measuring, without warm-up and pauses
        self._active_since: float | None = None    # rig time the present stretch of measuring began
        devices.route_events(self._device_event)
        self.position = tuple(self._read_back())
        self._estimate_s = self._point_estimates_s()
        self._left_estimate_s = sum(t for pid, t in self._estimate_s.items() if pid not in self.done_ids)

    # -- helpers -----------------------------------------------------------------------------
    def _device_event(self, kind: str, **fields) -> None:
        """A driver's retry or reconnect: into events.jsonl and onto the progress line."""
        self.writer.event(kind, rig_time_s=self.rig_time(), **fields)
        self._report(f"{kind} {fields.get('device', '')}: {fields.get('what', '')}")

    def rig_time(self) -> float:
        return self.dev.clock.now() - self.t0

    def _read_back(self) -> list[float]:
        return [*self.dev.stage.positions_deg(), *self.dev.arm.positions_deg()]

    def _report(self, message: str = "") -> None:
        self.progress(Progress(self.measured, len(self.plan.points), self.rig_time(), message, self.eta_rig_s()))

    def _point_estimates_s(self) -> dict[str, float]:
        """The plan's rig time of each point: the move from its predecessor in plan order (the
        first: from where the axes are) plus the nominal capture."""
        path = np.array([self.position, *(p.motors_deg for p in self.plan.points)], float)
        moves = travel_time_s(self.rig.axes, path[:-1], path[1:])
        return {p.point_id: float(t) + NOMINAL_CAPTURE_S for p, t in zip(self.plan.points, moves)}

    def _measuring(self, active: bool) -> None:
        """Start (True) or end (False) a stretch of rig time that counts as measuring for the ETA."""
        now = self.rig_time()
        if self._active_since is not None:
            self._active_s += now - self._active_since
        self._active_since = now if active else None

    def eta_rig_s(self) -> float:
        """Rig time (s) the points left will take: their plan estimate × (measured / estimated) so far.

        Warm-up and pauses are not measuring time, so they do not inflate the rate; E⊥ readings,
        darks and retries between points do, as they will recur.
        """
        active = self._active_s + (self.rig_time() - self._active_since if self._active_since is not None else 0.0)
        rate = active / self._done_estimate_s if self._done_estimate_s > 0 and active > 0 else 1.0
        return self._left_estimate_s * rate

    # -- stopping ----------------------------------------------------------------------------
    def request_stop(self, reason: str) -> None:
        """Finish the point in flight, park, lamp off. Only sets a flag: safe from a signal handler or thread."""
        if self.stop_reason is None:
            self.stop_reason = reason

    def request_abort(self, reason: str) -> None:
        """Stop the axes now, lamp off. Only sets a flag: safe from a signal handler or thread."""
        if self.abort_reason is None:
            self.abort_reason = reason

    @property
    def stop_requested(self) -> bool:
        return self.stop_reason is not None

    def _check_abort(self) -> None:
        """The clock's sleep check: an abort ends any sleep, even a move's."""
        if self.abort_reason is not None:
            raise AbortRequested(self.abort_reason)

    def _check_stop(self) -> None:
        """Raise AbortRequested or StopRequested if asked; the stop is logged when first honoured."""
        self._check_abort()
        if self.stop_reason is None:
            return
        if not self._stop_logged:
            self._stop_logged = True
            self.writer.event("stop_requested", reason=self.stop_reason, rig_time_s=self.rig_time())
            self._report(f"stopping: {self.stop_reason}")
        raise StopRequested(self.stop_reason)

    def _wait(self, seconds: float) -> None:
        """Let `seconds` of rig time pass, looking at the stop request at least every STOP_CHECK_S."""
        left = seconds
        self._check_stop()
        while left > 0:
            step = min(left, self.STOP_CHECK_S)
            self.dev.clock.sleep(step)
            left -= step
            self._check_stop()

    def _start_move(self, target: tuple[float, float, float, float]) -> None:
        """Start all four axes together toward `target`, never through a forbidden zone.

        The planner already routes around the zones; this guards the moves it did not
        plan: the first one of a resume, a retry's, the park.
        """
        if self.moving_to is not None:          # interrupted on its way: where is it now?
            self.position = tuple(self._read_back())
        zone = path_crosses(self.position, target, zones_of(self.rig), self.rig.axes)
        if zone is not None:
            raise CollisionError(f"move from {self.position} to {target} (deg) would cross forbidden zone {zone!r}")
        for axis, value in zip((*self.dev.stage.axes, *self.dev.arm.axes), target):
            axis.start_move(value)
        self.moving_to = target

    def _move(self, target: tuple[float, float, float, float]) -> None:
        """Be at `target`: wait for the move already under way there, else start one, then wait."""
        if self.moving_to != target:
            self._start_move(target)
        timeout = (self.MOVE_TIMEOUT_FACTOR * move_time_s(self.rig, self.position, target)
                   + self.MOVE_TIMEOUT_MARGIN_S)
        for axis in (*self.dev.stage.axes, *self.dev.arm.axes):
            axis.wait(timeout)
        self.position, self.moving_to = target, None

    # -- phases ------------------------------------------------------------------------------
    def _log_identities(self) -> None:
        ids = self.dev.identities()
        self.writer.event("devices", identities=ids, simulated=self.dev.simulated)
        self.writer.update_manifest(rig={**self.writer.manifest.get("rig", {}), "identities": ids})

    def _warm_up(self) -> None:
        cfg = self.campaign.lamp
        lamp = self.dev.lamp
        lamp.set_current(0.0)
        lamp.set_output(True)
        lamp.set_current(self.rig.lamp.current_a, ramp_s=self.rig.lamp.ramp_s)
        start = self.rig_time()
        self.writer.event("lamp_on", current_a=lamp.measure_current_a(), voltage_v=lamp.measure_voltage_v(),
                          rig_time_s=start)
        self._report("lamp warm-up")
        self._wait(cfg.warmup_min_s)
        previous = self.dev.meter.read().illuminance_lx
        while True:
            self._wait(cfg.warmup_check_s)
            now = self.dev.meter.read().illuminance_lx
            change = abs(now - previous) / max(abs(now), 1e-300)
            elapsed = self.rig_time() - start
            if change < cfg.warmup_stable_rel or elapsed >= cfg.warmup_max_s:
                break
            previous = now
        self.lamp_ref_v = lamp.measure_voltage_v()
        self.writer.event("warmup_stable" if change < cfg.warmup_stable_rel else "warmup_not_stable",
                          illuminance_lx=now, change_rel=change, warmup_s=elapsed, lamp_voltage_v=self.lamp_ref_v,
                          rig_time_s=self.rig_time())

    def _lamp_problem(self) -> str | None:
        """Lamp current or voltage outside tolerance (a burn-out shows as no current), else None."""
        sus = self.campaign.suspenders
        current = self.dev.lamp.measure_current_a()
        wanted = self.rig.lamp.current_a
        if abs(current - wanted) > sus.lamp_current_tolerance_rel * wanted:
            return (f"lamp current {current:.3f} A at {self.dev.lamp.measure_voltage_v():.2f} V with {wanted:.3f} A "
                    "set" + (": lamp burnt out or circuit open"
                             if current < self.LAMP_CURRENT_MIN_FRACTION * wanted else ""))
        voltage = self.dev.lamp.measure_voltage_v()
        if self.lamp_ref_v and abs(voltage - self.lamp_ref_v) > sus.lamp_voltage_tolerance_rel * self.lamp_ref_v:
            return f"lamp voltage {voltage:.3f} V, {self.lamp_ref_v:.3f} V after warm-up"
        return None

    def _probe(self, device: str) -> Callable[[], str | None]:
        """A harmless exchange with `device`: None when it answers again."""
        actions = {"lamp": self.dev.lamp.measure_current_a, "meter": self.dev.meter.read,
                   "camera": self.dev.camera.identity,
                   **{ax.name: ax.position_deg for ax in (*self.dev.stage.axes, *self.dev.arm.axes)}}
        action = actions.get(device, self._read_back)

        def probe() -> str | None:
            try:
                action()
                return None
            except DeviceError as exc:
                return str(exc)
        return probe

    def _suspend(self, device: str, reason: str, problem: Callable[[], str | None], *, rewarm: bool = False) -> None:
        """Pause until `problem()` clears (checked every check_interval_s), or stop after max_wait_s.

        `max_wait_s` bounds the rig time of the whole pause, the checks' own time included.
        Points waiting for E⊥ keep the last good reading; the caller re-takes the affected points.
        """
        sus = self.campaign.suspenders
        self._measuring(False)
        if self.pending:
            self._write_pending(self.reading, None)
        self.writer.event("suspended", device=device, reason=reason, rig_time_s=self.rig_time())
        self._report(f"PAUSED ({device}): {reason}")
        start = self.rig_time()
        while (still := problem()) is not None:
            waited = self.rig_time() - start
            if waited >= sus.max_wait_s:
                self.writer.event("suspend_timeout", device=device, reason=still, waited_s=waited,
                                  rig_time_s=self.rig_time())
                raise DeviceError(device, f"paused {waited:.0f} s and still: {still}")
            self._wait(min(sus.check_interval_s, sus.max_wait_s - waited))
            self._report(f"PAUSED ({device}) {self.rig_time() - start:.0f} s: {still}")
        waited = self.rig_time() - start
        self.writer.event("resumed", device=device, waited_s=waited, rig_time_s=self.rig_time())
        self._report(f"resumed after {waited:.0f} s ({device})")
        if rewarm:
            self._warm_up()
        self.reading = None            # the next E⊥ reading starts afresh: nothing to interpolate across a pause
        self._measuring(True)

    def _answering(self, action: Callable[[], T]) -> T:
        """Run a device exchange; while a device stops answering, pause for it, then try again."""
        while True:
            try:
                return action()
            except DeviceError as exc:
                if not exc.unanswered:
                    raise
                self._suspend(exc.device, str(exc), self._probe(exc.device))

    def _read_illuminance(self, *, pause: bool = True) -> IlluminanceEstimate:
        """E⊥ from `illuminance.readings` meter readings; a meter that stops answering pauses the
        run (`pause`) or raises its DeviceError."""
        def take() -> list[IlluminanceReading]:
            return [self.dev.meter.read() for _ in range(self.campaign.illuminance.readings)]
        readings = self._answering(take) if pause else take()
        values = np.array([r.illuminance_lx for r in readings])
        if not values.mean() > 0:
            raise DeviceError("meter", f"E⊥ reads {values.mean():g} lx (photocurrent {readings[0].photocurrent_a:g} A):"
                                       " no light on the detector")
        est = estimate(values, self.rig_time(), self.rig.meter.repeatability_rel, self.rig.meter.calibration_u_rel)
        self.writer.event("illuminance", illuminance_normal_lx=est.value_lx, u_lx=est.u_lx,
                          readings=est.n, photocurrent_a=float(np.mean([r.photocurrent_a for r in readings])),
                          calibration_lx_per_a=readings[0].calibration_lx_per_a, rig_time_s=est.rig_time_s)
        return est

    def _new_reading(self) -> list[PlannedPoint]:
        """Measure E⊥ and drift-correct the points since the previous reading; returns points to re-take.

        A change beyond `suspenders.illuminance_drift_limit_rel` since the previous reading
        is not drift to interpolate but an event: those points are discarded, the run pauses
        until the lamp is steady again, and they are measured again.
        """
        est = self._read_illuminance()
        before = self.reading
        if self._jumped(before, est):
            retake = self._discard_pending(len(self.pending), "illuminance jump")
            self._limit_retakes(retake, before, est)
            reason = f"E⊥ {est.value_lx:.1f} lx, {before.value_lx:.1f} lx at the previous reading"
            self._suspend("illuminance", reason, self._illuminance_unsteady)
            est = self._read_illuminance()
        else:
            retake = []
            if self.pending:
                self._write_pending(before, est)
        self.reading = est
        self._points_since_reading = 0
        return retake

    def _jumped(self, before: IlluminanceEstimate | None, after: IlluminanceEstimate) -> bool:
        """E⊥ changed beyond `suspenders.illuminance_drift_limit_rel` since the previous reading."""
        limit = self.campaign.suspenders.illuminance_drift_limit_rel
        return before is not None and abs(after.value_lx - before.value_lx) > limit * before.value_lx

    def _discard_pending(self, n: int, reason: str) -> list[PlannedPoint]:
        """Discard the last `n` points waiting for E⊥ (they are measured again); returns their points."""
        dropped = self.pending[len(self.pending) - n:]
        del self.pending[len(self.pending) - n:]
        points = [m.point for m in dropped]
        if points:
            self.measured -= len(points)
            self._left_estimate_s += sum(self._estimate_s[p.point_id] for p in points)
            self.writer.event("points_discarded", point_ids=[p.point_id for p in points], reason=reason,
                              rig_time_s=self.rig_time())
        return points

    def _limit_retakes(self, discarded: list[PlannedPoint], before: IlluminanceEstimate,
                       after: IlluminanceEstimate) -> None:
        """Fail the run once a point has been discarded for an E⊥ jump more than MAX_RETAKES times.

        Failing, not measuring on with flagged points: a limit the lamp and meter cannot meet
        would discard every batch again, for hours of lamp life, and the points it keeps would
        not meet the operator's stated limit. The completed points are kept; after raising the
        limit (or fixing the lamp) `--resume` measures the rest.
        """
        self._discards.update(p.point_id for p in discarded)
        worst = max(discarded, key=lambda p: self._discards[p.point_id], default=None)
        if worst is None or self._discards[worst.point_id] <= self.MAX_RETAKES:
            return
        limit = self.campaign.suspenders.illuminance_drift_limit_rel
        change = abs(after.value_lx - before.value_lx) / before.value_lx
        raise DeviceError("illuminance", (
            f"point {worst.point_id} discarded {self._discards[worst.point_id]} times for an E⊥ jump beyond "
            f"suspenders.illuminance_drift_limit_rel = {limit:g} (last change {change:.2g}, meter repeatability "
            f"{self.rig.meter.repeatability_rel:g}); raise the limit above the lamp's drift between readings, "
            "or check the lamp, then continue with --resume"))

    def _illuminance_unsteady(self) -> str | None:
        """Two meter readings a check interval apart differ by more than the warm-up criterion."""
        first = self.dev.meter.read().illuminance_lx
        self._wait(self.campaign.lamp.warmup_check_s)
        second = self.dev.meter.read().illuminance_lx
        change = abs(second - first) / max(abs(second), 1e-300)
        if change >= self.campaign.lamp.warmup_stable_rel or not second > 0:
            return f"E⊥ still changing: {first:.1f} → {second:.1f} lx"
        return None

    def _write_pending(self, before: IlluminanceEstimate, after: IlluminanceEstimate | None) -> None:
        """Append the pending points with E⊥ interpolated between `before` and `after` (or `before` alone)."""
        times = np.array([m.rig_time_s for m in self.pending])
        for k, m in enumerate(self.pending):
            if after is None:
                self._append(self._row(m, before.value_lx, before.u_lx, 0.0))
                continue
            e = interpolate(before, after, times[k:k + 1])
            self._append(self._row(replace(m, flags=m.flags + ("drift_corrected",)),
                                   float(e.value_lx[0]), float(e.u_lx[0]), float(e.u_drift_lx[0])))
        self.pending.clear()

    def _append(self, row: dict) -> None:
        self.writer.append_row(row)
        self.rows.append(row)

    def _measure_point(self, point: PlannedPoint, next_point: PlannedPoint | None = None) -> Measurement:
        """Move, read back, expose; the move to `next_point` starts before the frames are merged."""
        self._move(point.motors_deg)
        motors = tuple(self._read_back())
        angles = geo.forward_deg(*motors, phi_i_at_pole_deg=point.phi_i_deg, phi_o_at_pole_deg=point.phi_o_deg)
        time_utc, rig_time = utc_now(), self.rig_time()
        acquisition = acquire_point(self.dev.camera, self.settings, self.darks)
        if next_point is not None:
            self._start_move(next_point.motors_deg)      # merging and writing overlap the next move
        cap = reduce_point(acquisition)
        flags = list(cap.flags)
        m = np.radians(motors)
        if not roi_inside_spot(m[0], m[1], m[2], m[3], self.settings.roi_px, self.optics,
                               self.rig.geometry.spot_diameter_m / 2):
            flags.append("roi_unlit")
        measurement = Measurement(point, motors, angles, cap, tuple(flags), time_utc, rig_time)
        if cap.image_cd_m2 is not None:
            self.writer.write_image(point.point_id, cap.image_cd_m2, {
                "point_id": point.point_id, "theta_i_deg": float(angles.theta_i_deg),
                "phi_i_deg": float(angles.phi_i_deg), "theta_o_deg": float(angles.theta_o_deg),
                "phi_o_deg": float(angles.phi_o_deg), "exposures_s": list(cap.exposures_s),
                "roi_window": [cap.roi_window.x0, cap.roi_window.y0, cap.roi_window.width, cap.roi_window.height]})
        return measurement

    def _row(self, m: Measurement, e_perp_lx: float, u_e_perp_lx: float, u_drift_lx: float) -> dict:
        """The brdf.csv row of a measurement, given the E⊥ it gets (and how much of u(E⊥) is drift)."""
        cap, theta_i = m.capture, float(m.angles.theta_i_deg)
        res = brdf_from_luminance(cap.luminance_cd_m2, cap.u_luminance_cd_m2, e_perp_lx, u_e_perp_lx,
                                  theta_i, self.rig.geometry.angle_u_deg,
                                  grazing_limit_deg=self.campaign.limits.grazing_limit_deg)
        flags = m.flags + (("grazing_incidence",) if res.grazing_incidence else ())
        # relative to the luminance, or to its uncertainty where the ROI is (nearly) black
        lum = max(abs(cap.luminance_cd_m2), cap.u_luminance_cd_m2, 1e-30)
        budget = {
            "u_rel_noise": math.sqrt(max(cap.u_noise_cd_m2 ** 2 - cap.u_dark_cd_m2 ** 2, 0.0)) / lum,
            "u_rel_dark": cap.u_dark_cd_m2 / lum,
            "u_rel_texture": cap.u_texture_cd_m2 / lum,
            "u_rel_calibration": self.dev.camera.sensor.calibration_u_rel,
            "u_rel_illuminance": math.sqrt(max(u_e_perp_lx ** 2 - u_drift_lx ** 2, 0.0)) / e_perp_lx,
            "u_rel_drift": u_drift_lx / e_perp_lx,
            "u_rel_angle": math.tan(math.radians(min(theta_i, 89.9999))) * math.radians(self.rig.geometry.angle_u_deg),
        }
        return {
            "point_id": m.point.point_id, "series": m.point.series,
            "theta_i_deg": theta_i, "phi_i_deg": float(m.angles.phi_i_deg),
            "theta_o_deg": float(m.angles.theta_o_deg), "phi_o_deg": float(m.angles.phi_o_deg),
            "brdf_per_sr": float(res.brdf_per_sr), "u_brdf_per_sr": float(res.u_brdf_per_sr),
            "luminance_cd_m2": cap.luminance_cd_m2, "u_luminance_cd_m2": cap.u_luminance_cd_m2,
            "illuminance_lx": float(res.illuminance_lx), "illuminance_normal_lx": e_perp_lx,
            "stage_vertical_deg": m.motors_deg[0], "stage_normal_deg": m.motors_deg[1],
            "arm_azimuth_deg": m.motors_deg[2], "arm_polar_deg": m.motors_deg[3],
            "exposures_s": list(cap.exposures_s), "saturated_fraction": cap.saturated_fraction,
            "flags": ";".join(dict.fromkeys(flags)), "time_utc": m.time_utc, "rig_time_s": m.rig_time_s,
            "u_illuminance_normal_lx": u_e_perp_lx, "roi_std_cd_m2": cap.roi_std_cd_m2,
            "n_frames": cap.n_frames, "capture_time_s": cap.capture_time_s, **budget,
        }

    def _measure_guarded(self, point: PlannedPoint, next_point: PlannedPoint | None) -> list[PlannedPoint]:
        """Measure one point under the suspenders; returns the points to (re-)take before going on."""
        problem = self._answering(self._lamp_problem)
        if problem is not None:
            retake = self._discard_pending(min(1, len(self.pending)), "lamp")     # lit while the lamp failed?
            self._suspend("lamp", problem, self._lamp_problem, rewarm=True)
            return retake + [point]
        try:
            m = self._measure_point(point, next_point)
        except DeviceError as exc:
            if exc.unanswered:
                self._suspend(exc.device, str(exc), self._probe(exc.device))
                self.position = tuple(self._read_back())
                return [point]
            if not exc.transient:
                raise
            self.writer.event("retry", point_id=point.point_id, device=exc.device, error=str(exc),
                              rig_time_s=self.rig_time())
            self.position = tuple(self._read_back())
            m = self._measure_point(point, next_point)
            m = replace(m, flags=m.flags + ("retried",))
        self.measured += 1
        self._points_since_reading += 1
        self._done_estimate_s += self._estimate_s[point.point_id]
        self._left_estimate_s -= self._estimate_s[point.point_id]
        if self.interpolate:
            self.pending.append(m)
            # written ahead, so a crash before the next reading loses nothing
            self.writer.event("point_pending", row=self._row(m, self.reading.value_lx, self.reading.u_lx, 0.0))
        else:
            self._append(self._row(m, self.reading.value_lx, self.reading.u_lx, 0.0))
        return []

    # -- the run -----------------------------------------------------------------------------
    def _park(self) -> None:
        self._report("parking")
        try:
            self._move(self.PARK_DEG)
        except CollisionError as exc:
            self.writer.event("park_skipped", reason=str(exc), rig_time_s=self.rig_time())
            return
        self.writer.event("parked", position_deg=list(self.PARK_DEG), rig_time_s=self.rig_time())

    def _closing_reading(self) -> None:
        """After a graceful stop: one E⊥ reading brackets the points waiting for one; nothing waits.

        No point waits during the warm-up or a pause (a pause writes them first), so then
        there is no reading to take. A meter that does not answer leaves them with the last
        E⊥ (the exit path writes them); a jump beyond the drift limit discards them, so that
        `--resume` measures them again.
        """
        if not self.pending:
            return
        try:
            est = self._read_illuminance(pause=False)
        except DeviceError as exc:
            self.writer.event("closing_reading_failed", error=str(exc), rig_time_s=self.rig_time())
            return
        if self._jumped(self.reading, est):
            self._discard_pending(len(self.pending), "illuminance jump")
        else:
            self._write_pending(self.reading, est)

    def _measure_all(self) -> None:
        """Points in plan order, each series contiguous; re-takes go to the front of the queue."""
        series_of = {s.index: s for s in self.plan.series}
        queue = deque(p for p in self.plan.points if p.point_id not in self.done_ids)
        previous_series = None
        self._measuring(True)
        while queue:
            self._check_stop()
            point = queue[0]
            new_series = point.series != previous_series
            if new_series:
                self._move(point.motors_deg)      # the stage first, then E⊥ at the series' position
            seconds_since = self.rig_time() - self.reading.rig_time_s if self.reading else 0.0
            if self.reading is None or self.schedule.due(new_series, self._points_since_reading, seconds_since):
                queue.extendleft(reversed(self._new_reading()))
                point = queue[0]
            previous_series = point.series
            queue.popleft()
            retake = self._measure_guarded(point, queue[0] if queue else None)
            if retake:
                queue.extendleft(reversed(retake))
                continue
            s = series_of[point.series]
            self._report(f"θi={s.theta_i_deg:g}° φi={s.phi_i_deg:g}°")
            if not queue and self.reading is not None:
                queue.extend(self._new_reading())   # closing reading; re-takes if the lamp jumped
        self._measuring(False)

    def run(self) -> str:
        """Warm up, measure, and end `complete`, `interrupted` or `failed` (then the error is re-raised).

        From the first statement of the exit path on, no request can raise: the clock's sleep
        check is removed before the rig is made safe, and the flags are not looked at again.
        """
        status, error, graceful = "failed", None, False
        self.dev.clock.sleep_check = self._check_abort
        try:
            try:
                self._check_stop()            # asked before the run began: do not even switch the lamp on
                self._log_identities()
                self._warm_up()
                self._measure_all()
                status = "complete"
            except StopRequested:
                status, graceful = "interrupted", True
                self._closing_reading()
                self._park()
        except (AbortRequested, KeyboardInterrupt):
            status, graceful = "interrupted", False
        except Exception as exc:
            error = f"{type(exc).__name__}: {exc}"
            raise
        finally:
            self.dev.clock.sleep_check = None
            problems = self.dev.safe_state()          # first and always: lamp off, axes stopped
            self._record_exit(status, error, graceful, problems)
        return status

    def _record_exit(self, status: str, error: str | None, graceful: bool, problems: list[str]) -> None:
        """Events and manifest of how the run ended; written after the rig is safe."""
        try:
            if status == "interrupted":
                self.writer.event("interrupted", graceful=graceful, reason=self.abort_reason or self.stop_reason,
                                  rig_time_s=self.rig_time(), measured=self.measured)
            elif status == "failed":
                self.writer.event("failed", error=error, rig_time_s=self.rig_time(), measured=self.measured)
            if self.pending:     # no closing reading: keep the points with the last E⊥, uncorrected
                self.writer.event("pending_without_closing_reading", points=len(self.pending),
                                  rig_time_s=self.rig_time())
                self._write_pending(self.reading, None)
        finally:
            self.writer.event("safe_state", lamp_off=not any(p.startswith("lamp") for p in problems),
                              problems=problems, rig_time_s=self.rig_time())
            self.writer.update_manifest(
                status=status, finished_utc=utc_now(), rig_time_s=self.rig_time(),
                counts={"planned": self.plan.n_planned, "measured": self.measured,
                        "skipped": len(self.plan.skipped),
                        "not_measured": len(self.plan.points) - self.measured},
                uncertainty_budget=campaign_budget(self.rows, BUDGET_COLUMNS),
                **({"error": error} if error else {}))
