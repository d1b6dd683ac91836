"""The run engine: executes a plan on a set of devices and writes the dataset.

It owns the sequence (warm-up, E⊥ on a schedule, then per point: move, capture, reading, row, append) and the
exits: whatever happens, the lamp is switched off, the axes are stopped and the manifest says how the run ended
(rig.acquisition.outcome). It does I/O and bookkeeping; the physics it calls (kinematics, HDR merge, BRDF,
uncertainty, rows) is pure. An adaptive campaign's points arrive in batches from a `PointSource`. A measured point
waits in the ledger (rig.acquisition.ledger) for the E⊥ reading after it, written ahead; the ledger also holds the
checkpoints a tripped suspender rewinds to. The engine writes its phase to phase.json (rig.acquisition.phase).

Interruption: suspenders (rig.acquisition.suspenders) pause the run, and every tripped one is handled by
`Runner._suspend`. The operator's stop and abort requests (rig.acquisition.stopping) are honoured between points
and in every wait: a graceful stop finishes the point in flight, brackets the waiting points with a closing E⊥
reading and parks; an abort stops the axes now. Either way the exit path makes the rig safe first, and nothing
can interrupt it.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any, TypeVar

import numpy as np

from rig.acquisition.alignment import align_run
from rig.acquisition.attenuation import attenuation_for
from rig.acquisition.capturer import capturer_for
from rig.acquisition.eta import Eta, point_estimates_s
from rig.acquisition.ledger import Ledger
from rig.acquisition.moves import Motors, Mover
from rig.acquisition.outcome import UNKNOWN_FAILURE, RunEnding, Status, ending_of
from rig.acquisition.phase import PhaseFile
from rig.acquisition.rows import Measurement, RowConstants
from rig.acquisition.stopping import AbortRequested, StopRequested, StopRequests
from rig.acquisition.summary import run_summary
from rig.acquisition.suspenders import UNVOUCHED, Suspender, device_silent, hold, install
from rig.acquisition.tending import batch_while_tending, tended
from rig.acquisition.warmup import warm_up
from rig.config.campaign import Campaign
from rig.config.rigfile import RigConfig, camera_optics
from rig.core import events
from rig.core.errors import DeviceError
from rig.core.values import IlluminanceReading, PointCapture, Progress, ProgressCallback
from rig.data.campaign_runs import RunRecorder
from rig.data.dataset_writer import DatasetWriter, utc_now
from rig.data.images import point_image_metadata
from rig.drivers.interfaces import RigDevices
from rig.physics.budget import lobe_view_u_deg
from rig.physics.footprint import view_footprint_deg
from rig.physics.illuminance import IlluminanceEstimate, NoLightError, ReadingSchedule, estimate_of_readings
from rig.physics.optics import roi_inside_spot
from rig.planning.estimate import NOMINAL_CAPTURE_S, WarmupEstimate
from rig.planning.points import Plan, PlannedPoint, PointSource

T = TypeVar("T")


class Runner:
    """Runs one campaign; `run()` returns the final status (complete/interrupted/failed)."""

    #: Where the axes go after a graceful stop (home).
    PARK_DEG: Motors = (0.0, 0.0, 0.0, 0.0)

    def __init__(self, campaign: Campaign, plan: Plan, devices: RigDevices, writer: DatasetWriter,
                 rig: RigConfig, progress: ProgressCallback | None = None, done_rows: Sequence[dict] = (),
                 source: PointSource | None = None, warmup: WarmupEstimate | None = None):
        """`done_rows`: rows already in the dataset (a resume); their points are not measured again.
        `source`: where more points come from once the plan's are measured (an adaptive campaign)."""
        self.campaign, self.plan, self.writer, self.rig = campaign, plan, writer, rig
        self.dev = devices = tended(given := devices)     # runs of meter readings keep the lamp fed (frames: capturer)
        self.progress: ProgressCallback = progress or (lambda p: None)
        self.source = source
        self.settings = campaign.capture.settings()
        self.optics = camera_optics(rig)
        ill = campaign.illuminance
        self.schedule = ReadingSchedule(ill.remeasure, ill.every)
        self.runs = RunRecorder(writer, done_rows, campaign.lamp, rig, warmup)     # the manifest's `runs`
        self.t0 = devices.clock.now() - self.runs.offset_s          # rig time continues across resumes
        self.done_ids = {r["point_id"] for r in done_rows}
        self.requests = StopRequests(devices.clock, self._stop_honoured)
        self._wait = self.requests.wait
        self.reading: IlluminanceEstimate | None = None
        self._points_since_reading = 0
        self.lamp_ref_v: float | None = None       # lamp voltage when warm: the lamp suspender's reference
        self.eta = Eta(self.rig_time, self.runs.expected.seconds)
        g = rig.geometry
        constants = RowConstants(g.angle_u_deg, lobe_view_u_deg(g.angle_u_deg, g.readback_u_deg),
                                 campaign.limits.grazing_limit_deg, devices.camera.sensor.calibration_u_rel,
                                 readback_u_deg=g.readback_u_deg)
        self.ledger = Ledger(writer, done_rows, constants, ill.correction == "interpolate", self.eta, self.rig_time)
        self.phase = PhaseFile(writer.dir, self.rig_time)
        self.suspenders = install(campaign, rig, devices, lamp_reference_v=lambda: self.lamp_ref_v, wait=self._wait,
                                  mark=self.ledger.mark)
        given.route_events(self._device_event)         # from here on a driver's retry is reported
        self.capturer = capturer_for(devices.camera, self.settings, devices.clock,    # the capture path, chosen once
                                     attenuation_for(devices, rig.attenuator, self._device_event))
        self.footprint_deg = view_footprint_deg(self.optics, self.capturer.roi)
        self.mover = Mover(devices, rig)
        self.eta.plan(point_estimates_s(plan, self.mover.position, rig.axes, NOMINAL_CAPTURE_S), self.done_ids)

    # -- helpers -----------------------------------------------------------------------------
    def _event(self, kind: str, **fields: Any) -> None:
        self.writer.event(kind, rig_time_s=self.rig_time(), **fields)

    def _device_event(self, kind: str, **fields: Any) -> None:
        """A driver's retry or reconnect: into events.jsonl and onto the progress line."""
        self._event(kind, **fields)
        self._report(f"{kind} {fields.get('device', '')}: {fields.get('what', '')}")

    def rig_time(self) -> float:
        return self.dev.clock.now() - self.t0

    @property
    def measured(self) -> int:
        """Points measured and kept, those of a resumed run's dataset included."""
        return self.ledger.measured

    def _report(self, message: str = "") -> None:
        self.progress(Progress(self.measured, len(self.plan.points), self.rig_time(), message, self.eta.left_s()))

    # -- stopping (rig.acquisition.stopping) ------------------------------------------------
    def request_stop(self, reason: str) -> None:
        """Finish the point in flight, park, lamp off. Only sets a flag: safe from a signal handler or thread."""
        self.requests.request_stop(reason)

    def request_abort(self, reason: str) -> None:
        """Stop the axes now, lamp off. Only sets a flag: safe from a signal handler or thread."""
        self.requests.request_abort(reason)

    def _stop_honoured(self, reason: str) -> None:
        self.phase.set(events.STOPPING, reason)
        self.writer.event(events.STOP_REQUESTED, reason=reason, rig_time_s=self.rig_time())
        self._report(f"stopping: {reason}")

    # -- the lamp and E⊥ ---------------------------------------------------------------------
    def _warm_up(self) -> None:
        self.phase.set(events.WARMING_UP, "lamp switched on")
        self.lamp_ref_v = self.runs.warmed(warm_up(self.campaign.lamp, self.rig, self.dev, self._wait, self.rig_time,
                                                   self._event, self._report, self.eta), self.rig_time())

    def _read_illuminance(self, *, pause: bool = True) -> IlluminanceEstimate:
        """E⊥ from `illuminance.readings` meter readings, recorded in an `illuminance` event; a meter that stops
        answering pauses the run (`pause`) or raises its DeviceError, and so does a batch that saw no light
        (rig.physics.illuminance.estimate_of_readings)."""
        def take() -> list[IlluminanceReading]:
            return [self.dev.meter.read() for _ in range(self.campaign.illuminance.readings)]
        readings, meter = self._answering(take) if pause else take(), self.rig.meter
        try:
            est = estimate_of_readings(readings, self.rig_time(), meter.repeatability_rel, meter.calibration_u_rel,
                                       meter.range_u_rel)
        except NoLightError as exc:
            raise DeviceError("meter", str(exc)) from None
        self.writer.event(events.ILLUMINANCE, illuminance_normal_lx=est.value_lx, u_lx=est.u_lx, readings=est.n,
                          photocurrent_a=float(np.mean([r.photocurrent_a for r in readings])),
                          calibration_lx_per_a=readings[0].calibration_lx_per_a, rig_time_s=est.rig_time_s)
        return est

    def _new_reading(self) -> list[PlannedPoint]:
        """Check the lamp, measure E⊥ and drift-correct the points since the previous reading; returns points to
        re-take (a lamp out of tolerance or an E⊥ jump trips its suspender, and E⊥ is read again once the lamp is
        steady; a meter that sees no light because the lamp went out since the check pauses for the lamp's
        suspender instead of failing the run)."""
        retake = self._suspend(*tripped) if (tripped := self.suspenders.tripped(self._answering, now=True)) else []
        while True:
            try:
                est = self._read_illuminance()
                break
            except DeviceError:
                if not (tripped := self.suspenders.tripped(lambda check: check(), now=True)):
                    raise
                retake += self._suspend(*tripped)
        before = self.reading
        jump = self.suspenders.illuminance
        reason = jump.jump(before, est)
        if reason is not None:
            retake += self._suspend(jump, reason)
            est = self._read_illuminance()
        else:
            self.ledger.write_pending(before, est)
        self.reading = est
        self._points_since_reading = 0
        return retake

    # -- suspenders --------------------------------------------------------------------------
    def _suspend(self, suspender: Suspender, reason: str) -> list[PlannedPoint]:
        """Handle a tripped suspender, whichever it is: discard the points it says (failing the run if
        one was discarded too often), pause until its check clears, and return the points to re-take."""
        retake = self._rewind(suspender)
        suspender.discarded([p.point_id for p in retake])
        self._pause(suspender, reason)
        return retake

    def _rewind(self, suspender: Suspender) -> list[PlannedPoint]:
        """Discard the points waiting for E⊥ since the checkpoint `suspender` names (they are measured again)."""
        return self.ledger.rewind(suspender.rewind_to, suspender.discard_reason or UNVOUCHED)

    def _pause(self, suspender: Suspender, reason: str) -> None:
        """Pause until `suspender.check()` clears, or stop after max_wait_s (rig.acquisition.suspenders.hold);
        then re-warm if it says so. Points waiting for E⊥ keep the last good reading; nothing is interpolated
        across a pause."""
        self.eta.measuring(False)
        self.phase.set(events.PAUSED, f"{suspender.name}: {reason}")
        self.ledger.write_pending(self.reading, None)
        hold(suspender, reason, self.campaign.suspenders, self.writer.event, self.rig_time, self._wait, self._report)
        if suspender.rewarm:
            self._warm_up()
        self.reading = None            # the next E⊥ reading starts afresh
        self.eta.measuring(True)
        self.phase.set(events.MEASURING)

    def _answering(self, action: Callable[[], T]) -> T:
        """Run a device exchange; while a device stops answering, pause for it, then try again."""
        while True:
            try:
                return action()
            except DeviceError as exc:
                if not exc.unanswered:
                    raise
                self._suspend(device_silent(self.dev, exc.device), str(exc))

    def _align(self) -> None:
        """Campaign `alignment`: the arm aligned on the sample's specular peak (rig.acquisition.alignment)."""
        if (spec := self.campaign.alignment) is not None:
            self.phase.set(events.ALIGNING)
            found = align_run(spec, self.writer.manifest, self.mover, self._capture, self._event,
                              self.writer.update_manifest, self._alignment_step)
            g = self.rig.geometry
            u_view = lobe_view_u_deg(g.angle_u_deg, g.readback_u_deg, found.u_deg)
            self.ledger.constants = replace(self.ledger.constants, lobe_view_u_deg=u_view)

    def _alignment_step(self, step: int, steps: int) -> None:
        """Before each step of an alignment scan: progress, and a stop request honoured (within one step)."""
        self._report(f"aligning the arm on the specular peak: step {step + 1} of {steps}")
        self.requests.check_stop()

    def _capture(self) -> PointCapture:
        return self.capturer.acquire().reduce()

    # -- one point ---------------------------------------------------------------------------
    def _take_point(self, point: PlannedPoint, next_point: PlannedPoint | None) -> list[PlannedPoint]:
        """Measure one point under the suspenders; returns the points to (re-)take before going on,
        this one among them if a suspender tripped before or while it was measured."""
        if tripped := self.suspenders.tripped(self._answering):
            return self._suspend(*tripped) + [point]
        self.ledger.started()
        try:
            m = self._measure_point(point, next_point)
        except DeviceError as exc:
            if exc.unanswered:
                retake = self._suspend(device_silent(self.dev, exc.device), str(exc))
                self.mover.resync()
                return retake + [point]
            if not exc.transient:
                raise
            self.writer.event(events.RETRY, point_id=point.point_id, device=exc.device, error=str(exc),
                              rig_time_s=self.rig_time())
            self.mover.resync()
            m = self._measure_point(point, next_point)
            m = replace(m, flags=m.flags + ("retried",))
        assert self.reading is not None, "points are measured after an E⊥ reading"
        self.ledger.keep(m, self.reading)
        self._points_since_reading += 1
        return []

    def _measure_point(self, point: PlannedPoint, next_point: PlannedPoint | None) -> Measurement:
        """Move, read back, expose; the move to `next_point` starts before the frames are merged."""
        motors, angles = self.mover.arrive(point)
        time_utc, rig_time = utc_now(), self.rig_time()
        acquisition = self.capturer.acquire()
        if next_point is not None:
            self.mover.start(next_point.motors_deg)      # merging and writing overlap the next move
        cap = acquisition.reduce()
        m = np.radians(motors)
        lit = roi_inside_spot(m[0], m[1], m[2], m[3], self.settings.roi_px, self.optics,
                              self.rig.geometry.spot_diameter_m / 2)
        measurement = Measurement(point, motors, angles, cap, cap.flags + (() if lit else ("roi_unlit",)),
                                  time_utc, rig_time, self.footprint_deg)
        if cap.image_cd_m2 is not None:
            self.writer.write_image(point.point_id, cap.image_cd_m2,
                                    point_image_metadata(point.point_id, angles, cap.exposures_s, cap.roi_window))
        return measurement

    # -- the run -----------------------------------------------------------------------------
    def _measure_all(self) -> None:
        """Points in plan order, each series contiguous; re-takes go to the front of the queue."""
        series_of = {s.index: s for s in self.plan.series}
        queue = deque(p for p in self.plan.points if p.point_id not in self.done_ids)
        previous_series = None
        self.eta.measuring(True)
        self.phase.set(events.MEASURING)
        while queue:
            self.requests.check_stop()
            point = queue[0]
            new_series = point.series != previous_series
            if new_series:
                self.mover.move(point.motors_deg)      # the stage first, then E⊥ at the series' position
            seconds_since = self.rig_time() - self.reading.rig_time_s if self.reading else 0.0
            if self.reading is None or self.schedule.due(new_series, self._points_since_reading, seconds_since):
                queue.extendleft(reversed(self._new_reading()))
                point = queue[0]
            previous_series = point.series
            queue.popleft()
            retake = self._take_point(point, queue[0] if queue else None)
            if retake:
                queue.extendleft(reversed(retake))
                continue
            s = series_of[point.series]
            self._report(f"θi={s.theta_i_deg:g}° φi={s.phi_i_deg:g}°")
            if not queue and self.reading is not None:
                queue.extend(self._new_reading())   # closing reading; re-takes if the lamp jumped
            if not queue:
                queue.extend(self._more_points())
        self.eta.measuring(False)

    def _more_points(self) -> list[PlannedPoint]:
        """The source's next batch (every row final: the closing reading came first), added to the plan."""
        batch = batch_while_tending(self.source, self.ledger.rows, self.dev.clock, self._event) if self.source else []
        self.plan = replace(self.plan, points=self.plan.points + tuple(batch))
        self.eta.add(point_estimates_s(replace(self.plan, points=tuple(batch)), self.mover.position, self.rig.axes,
                                       NOMINAL_CAPTURE_S))
        return batch

    def _closing_reading(self) -> None:
        """After a graceful stop: a lamp check and one E⊥ reading bracket the points waiting for one; nothing waits.

        No point waits during the warm-up or a pause (a pause writes them first), so then there is nothing to take.
        A lamp out of tolerance discards those it has not vouched for; a meter that does not answer leaves them with
        the last E⊥ (the exit path writes them); a jump beyond the drift limit discards them (`--resume` retakes)."""
        if not self.ledger.pending:
            return
        try:
            if tripped := self.suspenders.tripped(lambda check: check(), now=True):
                self._rewind(tripped[0])
            est = self._read_illuminance(pause=False)
        except DeviceError as exc:
            self.writer.event(events.CLOSING_READING_FAILED, error=str(exc), rig_time_s=self.rig_time())
            return
        jump = self.suspenders.illuminance
        if jump.jump(self.reading, est) is not None:
            self._rewind(jump)
        else:
            self.ledger.write_pending(self.reading, est)

    def run(self) -> Status:
        """Warm up, measure, and end `complete`, `interrupted` or `failed` (then the error is re-raised).

        From the first statement of the exit path on, no request can raise: the clock's sleep check is removed
        before the rig is made safe, and the flags are not looked at again."""
        ending = UNKNOWN_FAILURE
        self.dev.clock.sleep_check = self.requests.check_abort
        try:
            try:
                self.requests.check_stop()            # asked before the run began: do not even switch the lamp on
                self.phase.set(events.STARTING)
                ids = self.dev.identities()
                self.writer.event(events.DEVICES, identities=ids, simulated=self.dev.simulated)
                self.writer.update_manifest(rig={**self.writer.manifest.get("rig", {}), "identities": ids})
                self._warm_up()
                self._align()
                self._measure_all()
                ending = ending_of(None)
            except StopRequested as stop:
                ending = ending_of(stop)
                self._closing_reading()
                self._report("parking")
                self.mover.park(self.PARK_DEG, self._event)
        except (AbortRequested, KeyboardInterrupt) as abort:
            ending = ending_of(abort)
        except Exception as exc:
            ending = ending_of(exc)
            raise
        finally:
            self.dev.clock.sleep_check = None
            problems = self.dev.safe_state()          # first and always: lamp off, axes stopped
            self._record_exit(ending, problems)
            self.phase.set(events.CLOSING)
        return ending.status

    def _record_exit(self, ending: RunEnding, problems: list[str]) -> None:
        """Events and manifest of how the run ended; written after the rig is safe (the waiting points no lamp check
        vouched for are discarded: `--resume` measures them again)."""
        try:
            self.ledger.rewind(None, UNVOUCHED)
            if ending.status == "interrupted":
                self.writer.event(events.INTERRUPTED, graceful=ending.graceful, reason=self.requests.reason,
                                  rig_time_s=self.rig_time(), measured=self.measured)
            elif ending.status == "failed":
                self.writer.event(events.FAILED, error=ending.error, rig_time_s=self.rig_time(), measured=self.measured)
            if self.ledger.pending:     # no closing reading: keep the points with the last E⊥, uncorrected
                self.writer.event(events.PENDING_WITHOUT_CLOSING_READING, points=len(self.ledger.pending),
                                  rig_time_s=self.rig_time())
                self.ledger.write_pending(self.reading, None)
        finally:
            self.writer.event(events.SAFE_STATE, lamp_off=not any(p.startswith("lamp") for p in problems),
                              problems=problems, rig_time_s=self.rig_time())
            self.writer.update_manifest(**run_summary(ending, self.plan, self.measured, self.ledger.rows,
                                                      self.footprint_deg, self.rig_time()),
                                        runs=self.runs.ended(ending.status, self.rig_time()))
