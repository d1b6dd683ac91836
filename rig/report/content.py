"""What a measurement report says, collected from a dataset folder (docs/dataset.md) and optionally a fit
(`rig fit --json`) and road-lighting quantities (`rig export --format road`): plain values, no HTML, so that
the facts can be tested apart from their presentation (rig.report.html)."""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rig import __version__
from rig.core import events as kinds  # the kinds' names; `events` names a dataset's records here
from rig.core.jsonfile import JsonFileError, parse_json
from rig.data.campaign_runs import Run, runs_of
from rig.data.dataset_format import DatasetError
from rig.data.dataset_reader import Dataset, complete_lines
from rig.physics.budget import BUDGET_COLUMNS, NOT_STATED, campaign_budget, mark_not_stated, not_stated

#: Events of events.jsonl that record a fault the run survived (docs/dataset.md), in the report's order.
FAULT_EVENTS = (kinds.RETRY, kinds.RECONNECT, kinds.RECONNECT_FAILED, kinds.POINTS_DISCARDED, kinds.DEVICE_ERRORS,
                kinds.WARNING, kinds.WATCHDOG_EXPIRED_BEFORE_CONNECT, kinds.WATCHDOG_EXPIRED, kinds.WATCHDOG_OFF,
                kinds.WATCHDOG_FEED_FAILED, kinds.SUSPEND_TIMEOUT, kinds.CLOSING_READING_FAILED,
                kinds.SWITCH_OFF_RAMP_FAILED)
SECONDS_PER_HOUR = 3600.0


@dataclass(frozen=True)
class Pause:
    """A suspender's pause: the device and reason from `suspended`, how long from the `resumed` after it."""
    device: str
    reason: str
    waited_s: float | None            # None: the run never resumed (it timed out or ended)


@dataclass(frozen=True)
class IlluminanceTrend:
    """E⊥ readings (`illuminance` events) over the campaign's rig time (rig.data.campaign_runs: it continues
    across resumes), the run of each, and the lamp's drift they show within each run: a resume may follow a
    night with the lamp off, so no trend is drawn across one."""
    rig_time_s: np.ndarray
    e_perp_lx: np.ndarray
    u_lx: np.ndarray
    run: np.ndarray = field(default_factory=lambda: np.zeros(0, int))    # run index of each reading (none: one)

    def runs(self) -> list[np.ndarray]:
        """Each run's readings, as index arrays."""
        if self.run.size != self.rig_time_s.size:
            return [np.arange(self.rig_time_s.size)]
        return [np.flatnonzero(self.run == r) for r in np.unique(self.run)]

    @property
    def change_rel(self) -> float | None:
        """Last reading / first − 1: the drift over the whole campaign."""
        return float(self.e_perp_lx[-1] / self.e_perp_lx[0] - 1) if self.e_perp_lx.size >= 2 else None

    @property
    def slope_rel_per_h(self) -> float | None:
        """Least-squares slope of E⊥ against rig time within the runs (one slope, each run its own level),
        relative to the mean, per hour (a steady lamp drift)."""
        sxy = sxx = 0.0
        for k in self.runs():
            t, e = self.rig_time_s[k], self.e_perp_lx[k]
            sxy += float(np.sum((t - t.mean()) * (e - e.mean()))) if k.size else 0.0
            sxx += float(np.sum((t - t.mean()) ** 2)) if k.size else 0.0
        return sxy / sxx * SECONDS_PER_HOUR / float(np.mean(self.e_perp_lx)) if sxx > 0 else None

    def run_slopes_rel_per_h(self) -> list[float | None]:
        """Each run's own trend (as `slope_rel_per_h`), in run order."""
        return [IlluminanceTrend(self.rig_time_s[k], self.e_perp_lx[k], self.u_lx[k]).slope_rel_per_h
                for k in self.runs()]


@dataclass(frozen=True)
class Conditions:
    """How the run went: warm-up, E⊥, pauses by suspenders and the faults it survived."""
    warmup_s: float | None
    warmup_stable: bool | None        # None: no warm-up recorded (an imported dataset, or a resumed run)
    warmup_change_rel: float | None
    illuminance: IlluminanceTrend
    pauses: list[Pause]
    faults: dict[str, int]            # every FAULT_EVENTS kind, 0 when absent
    resumes: int
    rig_time_s: float | None
    runs: list[Run] = field(default_factory=list)      # the first run and each resume, with their warm-ups


@dataclass(frozen=True)
class Counts:
    planned: int | None
    measured: int
    skipped: int
    not_measured: int | None
    skipped_by_reason: dict[str, int]
    flagged: dict[str, int]           # points per quality flag


@dataclass(frozen=True)
class BudgetRow:
    component: str
    meaning: str
    median_u_rel: float
    p95_u_rel: float
    median_share: float


@dataclass(frozen=True)
class Series:
    index: int
    theta_i_deg: float
    phi_i_deg: float
    points: int


@dataclass(frozen=True)
class FitParameter:
    name: str
    value: float
    stderr: float | None


@dataclass(frozen=True)
class FitSummary:
    model: str
    parameters: list[FitParameter]
    metrics: dict[str, float]         # rmse [sr⁻¹], nrmse, ncc, where given
    diagnostics: dict[str, Any]
    record: dict                      # the fit as read, for the figures


@dataclass(frozen=True)
class RoadQuantity:
    name: str
    value: float
    u: float | None
    unit: str


@dataclass(frozen=True)
class RoadSummary:
    quantities: list[RoadQuantity]
    classes: dict[str, str]           # surface (R, C, N) and marking (R_L, Qd) classes
    notes: list[tuple[str, str]]      # method, uncertainty, extrapolation: as road.json says


@dataclass(frozen=True)
class ReportContent:
    dataset: Dataset
    sample_id: str
    sample_description: str
    campaign_name: str
    campaign_file: str
    campaign_sha256: str
    status: str
    created_utc: str
    finished_utc: str
    software_version: str             # the version that wrote the dataset
    report_version: str               # the version writing the report
    rig_name: str
    simulated: bool
    identities: dict[str, str]
    calibrations: list[tuple[str, str]]
    filters: list[dict[str, float]]
    series: list[Series]
    counts: Counts
    conditions: Conditions
    budget: list[BudgetRow]
    median_u_rel: float | None        # median of u_brdf_per_sr / brdf_per_sr over the points that have a u
    fit: FitSummary | None = None
    road: RoadSummary | None = None


def read_events(folder: Path) -> list[dict]:
    """events.jsonl's objects in order; a torn last line (docs/dataset.md) is ignored, a bad one elsewhere is
    an error naming the line."""
    path = folder / "events.jsonl"
    if not path.exists():
        return []
    text, _ = complete_lines(path, path.read_bytes())     # a last line without a newline: torn by a crash
    events = []
    for k, line in enumerate(text.split("\n"), 1):
        if not line.strip():
            continue
        try:
            obj = parse_json(line, path, first_line=k)
        except JsonFileError as exc:
            raise DatasetError(str(exc)) from None
        if isinstance(obj, dict):
            events.append(obj)
    return events


def count_events(events: list[dict]) -> dict[str, int]:
    """How many events of each kind."""
    return dict(Counter(str(e.get("event")) for e in events))


def _number(value: Any) -> float | None:
    return float(value) if isinstance(value, int | float) and not isinstance(value, bool) else None


def _pauses(events: list[dict]) -> list[Pause]:
    pauses: list[Pause] = []
    open_pause: dict | None = None
    for e in events:
        if e.get("event") == kinds.SUSPENDED:
            if open_pause is not None:
                pauses.append(Pause(str(open_pause.get("device", "")), str(open_pause.get("reason", "")), None))
            open_pause = e
        elif e.get("event") == kinds.RESUMED and open_pause is not None:
            pauses.append(Pause(str(open_pause.get("device", "")), str(open_pause.get("reason", "")),
                                _number(e.get("waited_s"))))
            open_pause = None
    if open_pause is not None:
        pauses.append(Pause(str(open_pause.get("device", "")), str(open_pause.get("reason", "")), None))
    return pauses


def _illuminance(runs: list[Run]) -> IlluminanceTrend:
    kept = [(t, e, u if u is not None else np.nan, run.index) for run in runs for t, e, u in run.illuminance]
    arr = np.array(kept, float).reshape(-1, 4)
    return IlluminanceTrend(arr[:, 0], arr[:, 1], arr[:, 2], arr[:, 3].astype(int))


def conditions(events: list[dict], manifest: Mapping) -> Conditions:
    """The run's conditions from its events and manifest."""
    warm = next((e for e in events if e.get("event") in (kinds.WARMUP_STABLE, kinds.WARMUP_NOT_STABLE)), None)
    counted = count_events(events)
    runs = runs_of(manifest, events)
    total = max([t for t in (_number(manifest.get("rig_time_s")), runs[-1].end_s if runs else None) if t is not None],
                default=None)                # an old dataset's manifest has its last run's rig time only
    return Conditions(
        warmup_s=_number(warm.get("warmup_s")) if warm else None,
        warmup_stable=(warm.get("event") == kinds.WARMUP_STABLE) if warm else None,
        warmup_change_rel=_number(warm.get("change_rel")) if warm else None,
        illuminance=_illuminance(runs), pauses=_pauses(events),
        faults={kind: counted.get(kind, 0) for kind in FAULT_EVENTS},
        resumes=len(manifest.get("resumes") or []), rig_time_s=total, runs=runs)


def counts(ds: Dataset) -> Counts:
    """Planned, measured and skipped points (the manifest's counts where the run wrote them), skipped points by
    reason and flagged points by flag (from the files)."""
    c = _part(ds.manifest, "counts")
    flagged = Counter(flag for flags in ds.flags for flag in flags)
    return Counts(planned=c.get("planned"), measured=len(ds), skipped=len(ds.skipped),
                  not_measured=c.get("not_measured"),
                  skipped_by_reason=dict(Counter(str(r.get("reason", "")) for r in ds.skipped).most_common()),
                  flagged=dict(flagged.most_common()))


def budget(ds: Dataset) -> list[BudgetRow]:
    """Median and 95th percentile of each u_rel_* column over the points that have them all (none in an import
    without them), largest median share of u² first (rig.physics.budget.campaign_budget)."""
    present = {c: m for c, m in BUDGET_COLUMNS.items() if c in ds.columns}
    if not present:
        return []
    table = np.column_stack([ds[c] for c in present])
    rows = [dict(zip(present, r)) for r in table[np.all(np.isfinite(table), axis=1)].tolist()]
    return [BudgetRow(b["component"], b["meaning"] + (" [correlated: shared by the points]" if b["correlated"] else ""),
                      b["median_u_rel"], b["p95_u_rel"], b["median_share_of_variance"])
            for b in mark_not_stated(campaign_budget(rows, present), not_stated(ds.manifest))]


def u_parts(ds: Dataset) -> list[tuple[str, str]]:
    """The two parts of u(f_r) (rig.physics.budget.SPLIT_COLUMNS), median relative over the points: what
    scatters the points about the truth, and the calibrations that move them all together."""
    f = ds["brdf_per_sr"]
    rows = []
    for column, label in (("u_brdf_point_per_sr", "u(f_r), point-to-point part (median, rel.)"),
                          ("u_brdf_correlated_per_sr", "u(f_r), correlated calibrations (median, rel.)")):
        u = ds[column] if column in ds.columns else np.full(f.shape, np.nan)
        ok = np.isfinite(u) & (f > 0)
        rows.append((label, _percent(float(np.median(u[ok] / f[ok]))) if np.any(ok) else "–"))
    return rows


def median_u_rel(ds: Dataset) -> float | None:
    """The typical relative standard uncertainty of f_r: the median of u/f_r where both are known and f_r > 0."""
    f, u = ds["brdf_per_sr"], ds["u_brdf_per_sr"]
    ok = np.isfinite(u) & (f > 0)
    return float(np.median(u[ok] / f[ok])) if np.any(ok) else None


def _calibrations(manifest: Mapping) -> list[tuple[str, str]]:
    config = _part(_part(manifest, "rig"), "config")
    camera, meter, geometry = (_part(config, k) for k in ("camera", "meter", "geometry"))
    rows = [("Camera calibration file", str(camera.get("calibration_file") or "none (sensor model)")),
            ("Camera calibration u (rel.)", _stated(manifest, "camera.calibration_u_rel", camera)),
            ("Meter calibration", f"{_sig(meter.get('calibration_lx_per_a'))} lx/A"),
            ("Meter calibration u (rel.)", _stated(manifest, "meter.calibration_u_rel", meter)),
            ("Meter repeatability (rel.)", _percent(meter.get("repeatability_rel"))),
            ("Lamp distance", f"{_sig(geometry.get('lamp_distance_m'))} m"),
            ("Camera distance", f"{_sig(geometry.get('camera_distance_m'))} m"),
            ("Axis angle u", f"{_sig(geometry.get('angle_u_deg'))}°")]
    geo_cal = _part(geometry, "calibration")     # filled from geometry.calibration_file (geometry-calibration.md)
    zeros = geo_cal.get("zero_offsets_deg")
    rows += ([("Geometry calibration", f"{geo_cal.get('file', '–')} of {geo_cal.get('date', '–')}"),
              ("Axis zero offsets", " / ".join(f"{_sig(z)}°" for z in zeros) if isinstance(zeros, list) else "–")]
             if geo_cal else [("Geometry calibration", "none (nominal axis zeros)")])
    alignment = manifest.get("alignment")
    if isinstance(alignment, Mapping):
        rows += [("Alignment: arm azimuth zero", f"{_sig(alignment.get('arm_azimuth_zero_deg'))}°"),
                 ("Alignment: arm polar zero", f"{_sig(alignment.get('arm_polar_zero_deg'))}°"),
                 ("Alignment u", f"{_sig(alignment.get('u_deg'))}°")]
    else:
        rows.append(("Alignment", "none (nominal arm zero)"))
    footprint = _part(manifest, "footprint")
    if "view_half_angle_deg" in footprint:
        rows.append(("View footprint (half-angle)", f"{_sig(footprint['view_half_angle_deg'])}°"))
    return rows


def _stated(manifest: Mapping, key: str, section: Mapping) -> str:
    """A calibration's u as the rig file stated it, or NOT_STATED (it is used as 0)."""
    return NOT_STATED if key in not_stated(manifest) else _percent(section.get(key.rpartition(".")[2]))


def _part(record: Mapping, key: str) -> Mapping:
    """An object inside the manifest, or an empty one where it is absent or not an object (an edited file):
    the report then says "–" for what it would have shown."""
    value = record.get(key)
    return value if isinstance(value, Mapping) else {}


def _sig(value: Any, digits: int = 4) -> str:
    """A number to `digits` significant digits, or – when absent."""
    v = _number(value)
    return "–" if v is None else f"{v:.{digits}g}"


def _percent(value: Any) -> str:
    v = _number(value)
    return "–" if v is None else f"{100 * v:.3g} %"


def _series(ds: Dataset) -> list[Series]:
    out = []
    for s in np.unique(ds["series"]).astype(int).tolist():
        theta_i, phi_i = ds.series_incidence_deg(s)
        out.append(Series(s, theta_i, phi_i, int(np.count_nonzero(ds["series"] == s))))
    return out


def fit_summary(fit: Mapping) -> FitSummary:
    """A fit record as `rig fit --json` writes it (model, params, stderr, metrics, diagnostics)."""
    params, stderr = fit["params"], fit.get("stderr") or {}
    return FitSummary(str(fit["model"]),
                      [FitParameter(str(k), float(v), _number(stderr.get(k))) for k, v in params.items()],
                      {k: float(v) for k, v in (fit.get("metrics") or {}).items() if _number(v) is not None},
                      dict(fit.get("diagnostics") or {}), dict(fit))


#: road.json's scalar quantities (rig.analysis.road): key, label, unit.
ROAD_QUANTITIES = (("R_L_mcd_m2_lx", "R_L (30 m geometry)", "mcd·m⁻²·lx⁻¹"), ("Qd_mcd_m2_lx", "Qd", "mcd·m⁻²·lx⁻¹"),
                   ("Q0", "Q0", "cd·m⁻²·lx⁻¹"), ("S1", "S1", "1"))


def road_summary(road: Mapping) -> RoadSummary:
    """road.json as `rig export --format road` writes it (docs/road-lighting.md)."""
    quantities = [RoadQuantity(label, float(road[key]), _number(road.get(f"u_{key}")), unit)
                  for key, label, unit in ROAD_QUANTITIES if _number(road.get(key)) is not None]
    if not quantities:
        raise ValueError("not a road.json from `rig export --format road` (no R_L, Qd, Q0 or S1)")
    classes = {f"surface {k}": str(v) for k, v in (road.get("surface_classes") or {}).items() if v is not None}
    classes |= {f"marking {k}": str(v) for k, v in (road.get("marking_classes") or {}).items() if v is not None}
    notes = [(k, str(road[k])) for k in ("method", "uncertainty", "extrapolated") if road.get(k)]
    return RoadSummary(quantities, classes, notes)


def collect(ds: Dataset, fit: Mapping | None = None, road: Mapping | None = None) -> ReportContent:
    """Everything the report shows, from a loaded dataset and the optional fit and road records."""
    m = ds.manifest
    campaign, sample, rig, software = (_part(m, k) for k in ("campaign", "sample", "rig", "software"))
    filters = _part(_part(rig, "config"), "attenuator").get("filters")
    events = read_events(ds.path)
    return ReportContent(
        dataset=ds, sample_id=ds.sample_id(),
        sample_description=str(sample.get("description") or ""),
        campaign_name=str(campaign.get("name") or "–"), campaign_file=str(campaign.get("file") or "–"),
        campaign_sha256=str(campaign.get("sha256") or "–"), status=str(m.get("status") or "–"),
        created_utc=str(m.get("created_utc") or "–"), finished_utc=str(m.get("finished_utc") or "–"),
        software_version=str(software.get("version") or "–"), report_version=__version__,
        rig_name=str(rig.get("name") or "–"), simulated=bool(rig.get("simulated")),
        identities={str(k): str(v) for k, v in _part(rig, "identities").items()},
        calibrations=_calibrations(m) + u_parts(ds),
        filters=[dict(f) for f in (filters if isinstance(filters, list) else []) if isinstance(f, Mapping)],
        series=_series(ds), counts=counts(ds), conditions=conditions(events, m), budget=budget(ds),
        median_u_rel=median_u_rel(ds),
        fit=fit_summary(fit) if fit is not None else None, road=road_summary(road) if road is not None else None)
