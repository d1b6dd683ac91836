"""The run engine: executes a plan on a set of devices and writes the dataset.

It owns the sequence (warm-up, E⊥ per series, move → capture → process →
append) and the exits: whatever happens, the lamp is switched off, the axes are
stopped and the manifest says how the run ended. It does I/O and bookkeeping;
the physics it calls (kinematics, HDR merge, BRDF and uncertainty) is pure.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from drivers.interfaces import DeviceError, RigDevices
from rig import geometry as geo
from rig.campaign import Campaign
from rig.capture import CaptureSettings, DarkFrameCache, capture_point
from rig.dataset import DatasetWriter, utc_now
from rig.images import write_luminance_exr
from rig.optics import CameraOptics, roi_inside_spot
from rig.pipeline import brdf_from_luminance
from rig.plan import Plan, PlannedPoint, move_time_s
from rig.rigconfig import RigConfig


@dataclass(frozen=True)
class IlluminanceEstimate:
    """E⊥ with its standard uncertainty, from `n` averaged meter readings at `rig_time_s`."""

    value_lx: float
    u_lx: float
    n: int
    rig_time_s: float


@dataclass
class Progress:
    done: int
    total: int
    rig_time_s: float
    message: str = ""


ProgressCallback = Callable[[Progress], None]


def capture_settings(campaign: Campaign) -> CaptureSettings:
    c = campaign.capture
    return CaptureSettings(roi_px=c.roi_px, probe_exposure_s=c.probe_exposure_s,
                           target_fraction=c.target_fraction, bracket_stops=c.bracket_stops,
                           max_exposures=c.max_exposures, frames_per_exposure=c.frames_per_exposure,
                           min_snr=c.min_snr, full_frame=c.save_images)


class Runner:
    """Runs one campaign; `run()` returns the final status (complete/interrupted/failed)."""

    #: Moves may take this much longer than predicted before the axis counts as stuck.
    MOVE_TIMEOUT_FACTOR = 2.0
    MOVE_TIMEOUT_MARGIN_S = 10.0
    #: Lamp current below this fraction of the setpoint stops the run (burn-out, open circuit).
    LAMP_CURRENT_MIN_FRACTION = 0.5

    def __init__(self, campaign: Campaign, plan: Plan, devices: RigDevices, writer: DatasetWriter,
                 rig: RigConfig, progress: ProgressCallback | None = None):
        self.campaign = campaign
        self.plan = plan
        self.dev = devices
        self.writer = writer
        self.rig = rig
        self.progress = progress or (lambda p: None)
        self.settings = capture_settings(campaign)
        self.darks = DarkFrameCache(frames_per_dark=self.settings.frames_per_exposure)
        self.optics = CameraOptics.from_config(rig)
        self.t0 = devices.clock.now()
        self.measured = 0
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

    def _move(self, target: tuple[float, float, float, float]) -> None:
        """Start all four axes together, then wait for each."""
        timeout = (self.MOVE_TIMEOUT_FACTOR * move_time_s(self.rig, self.position, target)
                   + self.MOVE_TIMEOUT_MARGIN_S)
        axes = (*self.dev.stage.axes, *self.dev.arm.axes)
        for axis, value in zip(axes, target):
            axis.start_move(value)
        for axis in axes:
            axis.wait(timeout)
        self.position = target

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
            if change < cfg.warmup_stable_rel:
                self.writer.event("warmup_stable", illuminance_lx=now, change_rel=change,
                                  warmup_s=elapsed, rig_time_s=self.rig_time())
                return
            if elapsed >= cfg.warmup_max_s:
                self.writer.event("warmup_not_stable", illuminance_lx=now, change_rel=change,
                                  warmup_s=elapsed, rig_time_s=self.rig_time())
                return
            previous = now

    def _check_lamp(self) -> None:
        """A burnt-out filament or an open lead shows as output current far below the setpoint."""
        current = self.dev.lamp.measure_current_a()
        wanted = self.rig.lamp.current_a
        if current < self.LAMP_CURRENT_MIN_FRACTION * wanted:
            voltage = self.dev.lamp.measure_voltage_v()
            raise DeviceError("lamp", f"output current {current:.3f} A at {voltage:.2f} V with {wanted:.3f} A set: "
                                      "lamp burnt out or circuit open")

    def _measure_illuminance(self, series: int) -> IlluminanceEstimate:
        n = self.campaign.illuminance.readings
        readings = [self.dev.meter.read() for _ in range(n)]
        values = np.array([r.illuminance_lx for r in readings])
        mean = float(values.mean())
        if not mean > 0:
            raise DeviceError("meter", f"E⊥ reads {mean:g} lx (photocurrent {readings[0].photocurrent_a:g} A): "
                                       "no light on the detector")
        if n >= 2:
            u_stat = float(values.std(ddof=1) / math.sqrt(n))
        else:
            u_stat = self.rig.meter.repeatability_rel * mean
        u = math.hypot(u_stat, self.rig.meter.calibration_u_rel * mean)
        est = IlluminanceEstimate(mean, u, n, self.rig_time())
        self.writer.event("illuminance", series=series, illuminance_normal_lx=mean, u_lx=u, readings=n,
                          photocurrent_a=float(np.mean([r.photocurrent_a for r in readings])),
                          calibration_lx_per_a=readings[0].calibration_lx_per_a, rig_time_s=est.rig_time_s)
        return est

    def _measure_point(self, point: PlannedPoint, e_perp: IlluminanceEstimate) -> dict:
        self._move(point.motors_deg)
        self._check_lamp()
        motors = self._read_back()
        achieved = geo.forward_deg(*motors, phi_i_at_pole_deg=point.phi_i_deg,
                                   phi_o_at_pole_deg=point.phi_o_deg)
        time_utc, rig_time = utc_now(), self.rig_time()
        cap = capture_point(self.dev.camera, self.settings, self.darks)
        theta_i = float(achieved.theta_i_deg)
        res = brdf_from_luminance(cap.luminance_cd_m2, cap.u_luminance_cd_m2, e_perp.value_lx, e_perp.u_lx,
                                  theta_i, self.rig.geometry.angle_u_deg,
                                  grazing_limit_deg=self.campaign.limits.grazing_limit_deg)
        flags = list(cap.flags) + (["grazing_incidence"] if res.grazing_incidence else [])
        m = np.radians(motors)
        if not roi_inside_spot(m[0], m[1], m[2], m[3], self.settings.roi_px, self.optics,
                               self.rig.geometry.spot_diameter_m / 2):
            flags.append("roi_unlit")
        row = {
            "point_id": point.point_id, "series": point.series,
            "theta_i_deg": theta_i, "phi_i_deg": float(achieved.phi_i_deg),
            "theta_o_deg": float(achieved.theta_o_deg), "phi_o_deg": float(achieved.phi_o_deg),
            "brdf_per_sr": float(res.brdf_per_sr), "u_brdf_per_sr": float(res.u_brdf_per_sr),
            "luminance_cd_m2": cap.luminance_cd_m2, "u_luminance_cd_m2": cap.u_luminance_cd_m2,
            "illuminance_lx": float(res.illuminance_lx), "illuminance_normal_lx": e_perp.value_lx,
            "stage_vertical_deg": motors[0], "stage_normal_deg": motors[1],
            "arm_azimuth_deg": motors[2], "arm_polar_deg": motors[3],
            "exposures_s": list(cap.exposures_s), "saturated_fraction": cap.saturated_fraction,
            "flags": ";".join(dict.fromkeys(flags)), "time_utc": time_utc, "rig_time_s": rig_time,
            "u_illuminance_normal_lx": e_perp.u_lx, "roi_std_cd_m2": cap.roi_std_cd_m2,
            "n_frames": cap.n_frames,
        }
        if cap.image_cd_m2 is not None:
            write_luminance_exr(self.writer.image_path(point.point_id), cap.image_cd_m2, {
                **{k: row[k] for k in ("theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg")},
                "point_id": point.point_id, "exposures_s": list(cap.exposures_s),
                "roi_window": [cap.roi_window.x0, cap.roi_window.y0, cap.roi_window.width,
                               cap.roi_window.height]})
        return row

    def _measure_with_retry(self, point: PlannedPoint, e_perp: IlluminanceEstimate) -> None:
        try:
            row = self._measure_point(point, e_perp)
        except DeviceError as exc:
            if not exc.transient:
                raise
            self.writer.event("retry", point_id=point.point_id, device=exc.device, error=str(exc),
                              rig_time_s=self.rig_time())
            self.position = tuple(self._read_back())
            row = self._measure_point(point, e_perp)
            row["flags"] = ";".join(f for f in (row["flags"], "retried") if f)
        self.writer.append_row(row)
        self.measured += 1

    # -- the run -----------------------------------------------------------------------------
    def run(self) -> str:
        status, error = "failed", None
        try:
            self._log_identities()
            self._warm_up()
            for series in self.plan.series:
                points = [p for p in self.plan.points if p.series == series.index]
                if not points:
                    continue
                self._move(points[0].motors_deg)
                e_perp = self._measure_illuminance(series.index)
                for point in points:
                    self._measure_with_retry(point, e_perp)
                    self._report(f"θi={series.theta_i_deg:g}° φi={series.phi_i_deg:g}°")
            status = "complete"
        except KeyboardInterrupt:
            status = "interrupted"
            self.writer.event("interrupted", rig_time_s=self.rig_time(), measured=self.measured)
        except Exception as exc:
            error = f"{type(exc).__name__}: {exc}"
            self.writer.event("failed", error=error, rig_time_s=self.rig_time(), measured=self.measured)
            raise
        finally:
            problems = self.dev.safe_state()
            self.writer.event("safe_state", lamp_off=not any(p.startswith("lamp") for p in problems),
                              problems=problems, rig_time_s=self.rig_time())
            self.writer.update_manifest(
                status=status, finished_utc=utc_now(), rig_time_s=self.rig_time(),
                counts={"planned": self.plan.n_planned, "measured": self.measured,
                        "skipped": len(self.plan.skipped),
                        "not_measured": len(self.plan.points) - self.measured},
                **({"error": error} if error else {}))
        return status
