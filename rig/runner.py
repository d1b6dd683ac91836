"""The run engine: executes a plan on a set of devices and writes the dataset.

It owns the sequence (warm-up, E⊥ on a schedule, move → capture → process →
append) and the exits: whatever happens, the lamp is switched off, the axes are
stopped and the manifest says how the run ended. It does I/O and bookkeeping;
the physics it calls (kinematics, HDR merge, BRDF, uncertainty) is pure.

Drift correction needs the E⊥ reading *after* a point, so with
`illuminance.correction: interpolate` a measured point is first written ahead
to events.jsonl (`point_pending`, fsync'ed: nothing is lost if the process
dies) and appended to brdf.csv once the next reading brackets it.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, replace
from typing import Callable, Sequence, TypeVar

import numpy as np

from drivers.interfaces import DeviceError, RigDevices
from rig import geometry as geo
from rig.budget import BUDGET_COLUMNS, campaign_budget
from rig.campaign import Campaign
from rig.capture import CaptureSettings, DarkFrameCache, PointCapture, acquire_point, reduce_point
from rig.collisions import path_crosses, zones_of
from rig.dataset import DatasetWriter, utc_now
from rig.illuminance import IlluminanceEstimate, ReadingSchedule, estimate, interpolate
from rig.images import write_luminance_exr
from rig.optics import CameraOptics, roi_inside_spot
from rig.pipeline import brdf_from_luminance
from rig.plan import Plan, PlannedPoint, move_time_s
from rig.rigconfig import RigConfig


@dataclass
class Progress:
    done: int
    total: int
    rig_time_s: float
    message: str = ""


ProgressCallback = Callable[[Progress], None]
T = TypeVar("T")


class CollisionError(RuntimeError):
    """A move would cross a forbidden zone of the rig configuration; nothing moved."""


class StopRequested(Exception):
    """A graceful stop (first Ctrl+C): raised between points, never inside one."""


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


def capture_settings(campaign: Campaign) -> CaptureSettings:
    c = campaign.capture
    return CaptureSettings(roi_px=c.roi_px, probe_exposure_s=c.probe_exposure_s,
                           target_fraction=c.target_fraction, bracket_stops=c.bracket_stops,
                           max_exposures=c.max_exposures, frames_per_exposure=c.frames_per_exposure,
                           min_snr=c.min_snr, full_frame=c.save_images, mode=c.mode, target_snr=c.target_snr,
                           max_frames=c.max_frames, bracket_count=c.bracket_count,
                           bracket_step_stops=c.bracket_step_stops, dark_max_age_s=c.dark_max_age_s)


class Runner:
    """Runs one campaign; `run()` returns the final status (complete/interrupted/failed)."""

    #: Moves may take this much longer than predicted before the axis counts as stuck.
    MOVE_TIMEOUT_FACTOR = 2.0
    MOVE_TIMEOUT_MARGIN_S = 10.0
    #: Lamp current below this fraction of the setpoint stops the run (burn-out, open circuit).
    LAMP_CURRENT_MIN_FRACTION = 0.5

    #: Where the axes go after a graceful stop (home).
    PARK_DEG = (0.0, 0.0, 0.0, 0.0)

    def __init__(self, campaign: Campaign, plan: Plan, devices: RigDevices, writer: DatasetWriter,
                 rig: RigConfig, progress: ProgressCallback | None = None, done_rows: Sequence[dict] = ()):
        """`done_rows`: rows already in the dataset (a resume); their points are not measured again."""
        self.campaign = campaign
        self.plan = plan
        self.dev = devices
        self.writer = writer
        self.rig = rig
        self.progress = progress or (lambda p: None)
        self.settings = capture_settings(campaign)
        self.darks = DarkFrameCache(frames_per_dark=self.settings.frames_per_exposure, clock=devices.clock)
        self.optics = CameraOptics.from_config(rig)
        ill = campaign.illuminance
        self.schedule = ReadingSchedule(ill.remeasure, ill.every)
        self.interpolate = ill.correction == "interpolate"
        self.t0 = devices.clock.now()
        self.rows: list[dict] = list(done_rows)     # written rows, for the campaign budget
        self.done_ids = {r["point_id"] for r in done_rows}
        self.measured = len(done_rows)
        self.stop_requested = False
        self.pending: list[Measurement] = []       # waiting for the next E⊥ reading
        self.reading: IlluminanceEstimate | None = None
        self._points_since_reading = 0
        self.lamp_ref_v: float | None = None       # lamp voltage when warm: the voltage suspender's reference
        self.moving_to: tuple[float, ...] | None = None   # target of a move started and not yet waited for
        devices.route_events(self._device_event)
        self.position = tuple(self._read_back())

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
        self.progress(Progress(self.measured, len(self.plan.points), self.rig_time(), message))

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
        self.dev.clock.sleep(cfg.warmup_min_s)
        previous = self.dev.meter.read().illuminance_lx
        while True:
            self.dev.clock.sleep(cfg.warmup_check_s)
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
                    "set" + (": lamp burnt out or circuit open" if current < 0.5 * wanted else ""))
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

        Points waiting for E⊥ keep the last good reading; the caller re-takes the affected points.
        """
        sus = self.campaign.suspenders
        if self.pending:
            self._write_pending(self.reading, None)
        self.writer.event("suspended", device=device, reason=reason, rig_time_s=self.rig_time())
        self._report(f"PAUSED ({device}): {reason}")
        waited = 0.0
        while (still := problem()) is not None:
            if waited >= sus.max_wait_s:
                self.writer.event("suspend_timeout", device=device, reason=still, waited_s=waited,
                                  rig_time_s=self.rig_time())
                raise DeviceError(device, f"paused {waited:.0f} s and still: {still}")
            self.dev.clock.sleep(sus.check_interval_s)
            waited += sus.check_interval_s
            self._report(f"PAUSED ({device}) {waited:.0f} s: {still}")
        self.writer.event("resumed", device=device, waited_s=waited, rig_time_s=self.rig_time())
        self._report(f"resumed after {waited:.0f} s ({device})")
        if rewarm:
            self._warm_up()
        self.reading = None            # the next E⊥ reading starts afresh: nothing to interpolate across a pause

    def _answering(self, action: Callable[[], T]) -> T:
        """Run a device exchange; while a device stops answering, pause for it, then try again."""
        while True:
            try:
                return action()
            except DeviceError as exc:
                if not exc.unanswered:
                    raise
                self._suspend(exc.device, str(exc), self._probe(exc.device))

    def _read_illuminance(self) -> IlluminanceEstimate:
        readings = self._answering(lambda: [self.dev.meter.read() for _ in range(self.campaign.illuminance.readings)])
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
        limit = self.campaign.suspenders.illuminance_drift_limit_rel
        if before is not None and abs(est.value_lx - before.value_lx) > limit * before.value_lx:
            retake = [m.point for m in self.pending]
            self.pending.clear()
            self.measured -= len(retake)
            self.writer.event("points_discarded", point_ids=[p.point_id for p in retake],
                              reason="illuminance jump", rig_time_s=self.rig_time())
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

    def _illuminance_unsteady(self) -> str | None:
        """Two meter readings a check interval apart differ by more than the warm-up criterion."""
        first = self.dev.meter.read().illuminance_lx
        self.dev.clock.sleep(self.campaign.lamp.warmup_check_s)
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
            write_luminance_exr(self.writer.image_path(point.point_id), cap.image_cd_m2, {
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
            retake = [self.pending.pop().point] if self.pending else []     # lit while the lamp failed?
            if retake:
                self.measured -= 1
                self.writer.event("points_discarded", point_ids=[retake[0].point_id], reason="lamp",
                                  rig_time_s=self.rig_time())
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
        if self.interpolate:
            self.pending.append(m)
            # written ahead, so a crash before the next reading loses nothing
            self.writer.event("point_pending", row=self._row(m, self.reading.value_lx, self.reading.u_lx, 0.0))
        else:
            self._append(self._row(m, self.reading.value_lx, self.reading.u_lx, 0.0))
        return []

    # -- the run -----------------------------------------------------------------------------
    def request_stop(self, reason: str) -> None:
        """Finish the point in flight, then stop cleanly (called from a signal handler)."""
        self.stop_requested = True
        self.writer.event("stop_requested", reason=reason, rig_time_s=self.rig_time())
        self._report(f"stopping after this point: {reason}")

    def _park(self) -> None:
        self._report("parking")
        try:
            self._move(self.PARK_DEG)
        except CollisionError as exc:
            self.writer.event("park_skipped", reason=str(exc), rig_time_s=self.rig_time())
            return
        self.writer.event("parked", position_deg=list(self.PARK_DEG), rig_time_s=self.rig_time())

    def _measure_all(self) -> None:
        """Points in plan order, each series contiguous; re-takes go to the front of the queue."""
        series_of = {s.index: s for s in self.plan.series}
        queue = deque(p for p in self.plan.points if p.point_id not in self.done_ids)
        previous_series = None
        while queue:
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
            if self.stop_requested:
                raise StopRequested
            if not queue and self.reading is not None:
                queue.extend(self._new_reading())   # closing reading; re-takes if the lamp jumped

    def run(self) -> str:
        status, error = "failed", None
        try:
            self._log_identities()
            self._warm_up()
            self._measure_all()
            status = "complete"
        except StopRequested:
            status = "interrupted"
            self.writer.event("interrupted", graceful=True, rig_time_s=self.rig_time(), measured=self.measured)
            if self.reading is not None:
                self._new_reading()          # brackets the points since the last reading (a jump: kept unbracketed)
            self._park()
        except KeyboardInterrupt:
            status = "interrupted"
            self.writer.event("interrupted", rig_time_s=self.rig_time(), measured=self.measured)
        except Exception as exc:
            error = f"{type(exc).__name__}: {exc}"
            self.writer.event("failed", error=error, rig_time_s=self.rig_time(), measured=self.measured)
            raise
        finally:
            if self.pending:     # no closing reading: keep the points with the last E⊥, uncorrected
                self.writer.event("pending_without_closing_reading", points=len(self.pending),
                                  rig_time_s=self.rig_time())
                self._write_pending(self.reading, None)
            problems = self.dev.safe_state()
            self.writer.event("safe_state", lamp_off=not any(p.startswith("lamp") for p in problems),
                              problems=problems, rig_time_s=self.rig_time())
            self.writer.update_manifest(
                status=status, finished_utc=utc_now(), rig_time_s=self.rig_time(),
                counts={"planned": self.plan.n_planned, "measured": self.measured,
                        "skipped": len(self.plan.skipped),
                        "not_measured": len(self.plan.points) - self.measured},
                uncertainty_budget=campaign_budget(self.rows, BUDGET_COLUMNS),
                **({"error": error} if error else {}))
        return status
