"""`rig plot`: PNG figures of a dataset, optionally with a fitted model (matplotlib, Agg, no pyplot state).

Per incidence series:
- `plane_sNN_tiXX_piYYY.png` (series NN at θi XX°, φi YYY°; like Spieringhs et al. 2023 Fig. 7): f_r in the plane of
  incidence against the signed viewing angle, positive on the lamp side (the
  retroreflection hemisphere), negative on the specular side; a polar panel
  (radius ∝ f_r, linear) and a Cartesian one (log f_r) with ± u error bars, the
  retro (θo = θi) and mirror (θo = −θi) directions marked and the fitted curve.
  A point belongs to the plane when its viewing direction lies within
  `PLANE_TOL_DEG` of it (angular distance of ωo from the plane); it is drawn at
  its projection onto the plane. At normal incidence (θi < 1°) the plane is the
  x–z plane (φ = 0°/180°).
- `lobe_sNN_tiXX_piYYY.png` (like Figs. 6/9): the 3D lobe, each measured point at
  f_r·ωo, the incident vector toward the lamp, the mirror direction, and the
  fitted surface f_fit(ωo)·ωo over the hemisphere.
With a fit (`{"model", "params", "metrics"?}` as `rig fit --json` writes):
- `fit_residuals.png`: fitted against measured f_r (log–log) and the relative
  residual against θo, every series (colour = θi on a colour scale, marker = φi; keys outside the data).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib import colormaps, rc_context
from matplotlib.axis import Axis
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import LogFormatterSciNotation, LogLocator, MaxNLocator, NullFormatter

from rig.data.dataset_format import DatasetError
from rig.data.dataset_reader import Dataset, load
from rig.data.output_folder import new_folder, require_new_output
from rig.physics.brdf_models import get_model
from rig.physics.geometry import (
    NORMAL_INCIDENCE_DEG,
    PLANE_TOL_DEG,
    mirror_direction,
    plane_axes,
    plane_offsets,
    sph_to_vec,
)

DPI = 110
#: The 3D lobe is seen from this far off the plane of incidence (degrees of azimuth): seen along the plane, one axis
#: is edge-on and its tick labels pile up.
LOBE_VIEW_OFF_PLANE_DEG = 55.0
#: The plane figure's text size (points): the report shows it at about two thirds of its width.
PLANE_FONT_PT = 11
MEASURED, FITTED, LAMP = "#1f77b4", "#d62728", "#ff7f0e"
RETRO_SHADE, SPECULAR_SHADE = "#fdd9b5", "#d6e6f5"
RETRO_TEXT, SPECULAR_TEXT = "#a0522d", "#2f5f8f"

Model = Callable[[np.ndarray, np.ndarray], np.ndarray]


def _record_model(fit: Mapping) -> Model:
    """f_fit(ωi, ωo) of a fit record."""
    model, params = get_model(fit["model"]), dict(fit["params"])
    return lambda wi, wo: model(np.broadcast_to(wi, np.shape(wo)), wo, params)


def _phi_shown(theta_i: float, phi_i: float) -> float:
    """φi in [0, 360), 0 at normal incidence (where the mean achieved φi is only the encoders' jitter)."""
    return 0.0 if theta_i < NORMAL_INCIDENCE_DEG else round(phi_i, 1) % 360


def _series_label(theta_i: float, phi_i: float) -> str:
    return f"θi = {theta_i:.1f}°, φi = {_phi_shown(theta_i, phi_i):.1f}°"


def series_stem(series: int, theta_i: float, phi_i: float) -> str:
    """The figures' file-name stem of a series: its number, θi and φi (two series at one θi differ by φi)."""
    return f"s{series:02d}_ti{theta_i:02.0f}_pi{round(_phi_shown(theta_i, phi_i)) % 360:03d}"


def _plane_curve(model: Model, wi: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    signed = np.linspace(-89.5, 89.5, 1791)
    s = np.radians(signed)[:, None]
    wo = np.cos(s) * np.array([0.0, 0.0, 1.0]) + np.sin(s) * t
    return signed, model(wi, wo)


def _stated(u: np.ndarray) -> np.ndarray:
    """Where a point has a u: an import without one (ALTA without `#VS`) leaves u_brdf_per_sr empty (NaN)."""
    return np.isfinite(u) & (u > 0)


def _measured_label(u: np.ndarray) -> str:
    stated = _stated(u)
    if not stated.any():
        return "measured (u not stated)"
    return "measured ± u" if stated.all() else "measured ± u (where stated)"


def _draw_polar(ax, signed, f, u, curve, theta_i) -> None:
    ax.set_theta_zero_location("N")
    ax.set_theta_direction(-1)          # positive (lamp side) to the right, as in the Cartesian panel
    ax.set_thetamin(-90)
    ax.set_thetamax(90)
    # a point without u reaches f; its error bar (NaN) is not drawn
    r_max = 1.1 * max(np.max(f + np.where(_stated(u), u, 0.0), initial=0.0),
                      np.max(curve[1]) if curve else 0.0) or 1.0
    ax.set_ylim(0, r_max)
    if curve:
        ax.plot(np.radians(curve[0]), curve[1], color=FITTED, lw=1.6, label="fit")
    bars = _stated(u)
    ax.errorbar(np.radians(signed[bars]), f[bars], yerr=u[bars], fmt="none", ecolor="0.5")
    ax.plot(np.radians(signed), f, "o", ms=3, color=MEASURED, label=_measured_label(u))
    ax.annotate("", xy=(np.radians(theta_i), r_max), xytext=(0, 0),
                arrowprops={"arrowstyle": "-|>", "color": LAMP, "lw": 2, "alpha": 0.8})
    ax.plot([], [], color=LAMP, lw=2, label="incident direction (lamp)")
    ax.yaxis.set_major_locator(MaxNLocator(4))
    ax.text(np.radians(45), 1.2 * r_max, "retro side", ha="left", color=RETRO_TEXT)
    ax.text(np.radians(-45), 1.2 * r_max, "specular side", ha="right", color=SPECULAR_TEXT)
    ax.set_xlabel("radius: f_r [sr⁻¹] (linear); angle: viewing angle in the plane [deg]", labelpad=-40)
    ax.figure.legend(*ax.get_legend_handles_labels(), loc="upper left", bbox_to_anchor=(0.02, 0.88), fontsize=10)


def _draw_cartesian(ax, signed, f, u, off, tol_deg, curve, theta_i) -> None:
    ax.axvspan(0, 90, color=RETRO_SHADE, alpha=0.5, lw=0)
    ax.axvspan(-90, 0, color=SPECULAR_SHADE, alpha=0.5, lw=0)
    ax.axvline(theta_i, color=LAMP, ls="--", lw=1.2, label=f"retroreflection (θo = θi = {theta_i:.1f}°)")
    ax.axvline(-theta_i, color=SPECULAR_TEXT, ls=":", lw=1.2, label="mirror direction")
    if curve:
        ax.plot(curve[0], curve[1], color=FITTED, lw=1.6, label="fit")
    bars = _stated(u)
    ax.errorbar(signed[bars], f[bars], yerr=u[bars], fmt="none", ecolor="0.5", capsize=2)
    dots = ax.scatter(signed, f, c=off, cmap="viridis", vmin=0, vmax=tol_deg, s=18, zorder=3,
                      edgecolors="k", linewidths=0.3, label=_measured_label(u))
    ax.figure.colorbar(dots, ax=ax, pad=0.01, label="distance of ωo from the plane [deg]")
    if f.size and np.all(f > 0):
        ax.set_yscale("log")
    ax.set_xlim(-90, 90)
    ax.set_xticks(np.arange(-90, 91, 30))
    ax.set_xlabel("signed viewing angle in the plane of incidence [deg]  (− specular side | + lamp side)")
    ax.set_ylabel("f_r [sr⁻¹]")
    ax.text(0.25, 1.01, "specular hemisphere", transform=ax.transAxes, ha="center", va="bottom", color=SPECULAR_TEXT)
    ax.text(0.75, 1.01, "retro hemisphere", transform=ax.transAxes, ha="center", va="bottom", color=RETRO_TEXT)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, fontsize=10)     # below the axis title


def plane_figure(ds: Dataset, series: int, model: Model | None = None, tol_deg: float = PLANE_TOL_DEG) -> Figure:
    """Plane-of-incidence figure of one series (module docstring); draw it within `rc_context` with font.size
    PLANE_FONT_PT, as `plot_plane` does."""
    theta_i, phi_i = ds.series_incidence_deg(series)
    t, n = plane_axes(theta_i, phi_i)
    rows = ds["series"] == series
    _, wo = ds.directions()
    off, signed = plane_offsets(wo[rows], t, n)
    keep = off <= tol_deg
    order = np.argsort(signed[keep])
    signed, off, f, u = (a[keep][order] for a in (signed, off, ds["brdf_per_sr"][rows], ds["u_brdf_per_sr"][rows]))
    wi = sph_to_vec(np.radians(theta_i), np.radians(phi_i))
    curve = _plane_curve(model, wi, t) if model else None
    fig = Figure(figsize=(14, 6.0))
    fig.suptitle(f"{ds.sample_id()} — {_series_label(theta_i, phi_i)}: {keep.sum()} of {rows.sum()} points "
                 f"within {tol_deg:g}° of the plane of incidence", fontsize=13)
    _draw_polar(fig.add_axes((0.045, 0.06, 0.36, 0.8), projection="polar"), signed, f, u, curve, theta_i)
    _draw_cartesian(fig.add_axes((0.5, 0.3, 0.42, 0.58)), signed, f, u, off, tol_deg, curve, theta_i)
    return fig


def plot_plane(ds: Dataset, series: int, out: Path, model: Model | None = None,
               tol_deg: float = PLANE_TOL_DEG) -> Path:
    """The plane-of-incidence figure of one series, as a PNG."""
    with rc_context({"font.size": PLANE_FONT_PT}):
        plane_figure(ds, series, model, tol_deg).savefig(out, dpi=DPI, bbox_inches="tight", pad_inches=0.2)
    return out


def _hemisphere_surface(model: Model, wi: np.ndarray) -> np.ndarray:
    """Points f_fit(ωo)·ωo on a (θ, φ) grid over the hemisphere, shape (Nθ, Nφ, 3)."""
    theta, phi = np.meshgrid(np.radians(np.linspace(0, 89, 60)), np.radians(np.linspace(0, 360, 121)),
                             indexing="ij")
    wo = sph_to_vec(theta, phi)
    return model(wi, wo)[..., None] * wo


def lobe_figure(ds: Dataset, series: int, model: Model | None = None) -> Figure:
    """3D lobe of one series: measured f_r·ωo, incident vector, fitted surface (module docstring). Seen from 60°
    off the plane of incidence, so that all three axes show their ticks; a few ticks per axis, none at the box's
    corners, the axis titles padded clear of them."""
    theta_i, phi_i = ds.series_incidence_deg(series)
    rows = ds["series"] == series
    _, wo = ds.directions()
    f = ds["brdf_per_sr"][rows]
    pts = f[:, None] * wo[rows]
    wi = sph_to_vec(np.radians(theta_i), np.radians(phi_i))
    surface = _hemisphere_surface(model, wi) if model else None
    reach = 1.15 * max(np.max(np.abs(pts)), np.max(np.abs(surface)) if surface is not None else 0.0)
    fig = Figure(figsize=(10, 7.5))
    ax: Any = fig.add_axes((0.0, 0.02, 0.78, 0.84), projection="3d")        # an Axes3D: mpl_toolkits has no stubs
    if surface is not None:
        ax.plot_surface(*np.moveaxis(surface, -1, 0), color=FITTED, alpha=0.18, lw=0.3, edgecolor="#e8a0a0",
                        rstride=3, cstride=3)
        ax.plot([], [], color=FITTED, lw=4, alpha=0.4, label="fit f_fit(ωo)·ωo")
    sc = ax.scatter(*pts.T, c=f, cmap="viridis", s=16, depthshade=False, label="measured f_r·ωo")
    ax.quiver(0, 0, 0, *(reach * wi), color=LAMP, lw=1.5, alpha=0.7, arrow_length_ratio=0.06)
    ax.text(*(1.08 * reach * wi), "ωi (lamp)", color=LAMP, fontsize=11)
    ax.plot(*np.stack([np.zeros(3), reach * mirror_direction(wi)]).T, color=SPECULAR_TEXT, ls="--", lw=1.2,
            label="mirror direction")
    ring = np.radians(np.linspace(0, 360, 181))
    ax.plot(reach * np.cos(ring), reach * np.sin(ring), 0 * ring, color="0.6", lw=0.8, label="sample plane")
    ax.plot([0, 0], [0, 0], [0, reach], color="0.4", ls=":", lw=1, label="normal z")
    ax.set_xlim(-reach, reach)
    ax.set_ylim(-reach, reach)
    ax.set_zlim(0, reach)
    ax.set_box_aspect((2, 2, 1.1))
    ax.view_init(elev=25, azim=(phi_i if theta_i >= NORMAL_INCIDENCE_DEG else 0.0) - LOBE_VIEW_OFF_PLANE_DEG)
    for axis, name, prune in ((ax.xaxis, "x", "both"), (ax.yaxis, "y", "both"), (ax.zaxis, "z", "lower")):
        axis.set_major_locator(MaxNLocator(4, prune=prune))          # no tick at the box's corners, where they meet
        axis.set_tick_params(labelsize=9, pad=1)
        axis.set_label_text(f"{name}·f_r [sr⁻¹]", fontsize=10)
        axis.labelpad = 20
    fig.colorbar(sc, cax=fig.add_axes((0.84, 0.2, 0.025, 0.55)), label="measured f_r [sr⁻¹]")
    fig.legend(*ax.get_legend_handles_labels(), loc="upper left", bbox_to_anchor=(0.01, 0.88), fontsize=9)
    fig.suptitle(f"{ds.sample_id()} — BRDF lobe, {_series_label(theta_i, phi_i)} ({rows.sum()} points)\n"
                 "radius ∝ f_r in the viewing direction", fontsize=12)
    return fig


def plot_lobe(ds: Dataset, series: int, out: Path, model: Model | None = None) -> Path:
    """The lobe figure of one series, as a PNG."""
    lobe_figure(ds, series, model).savefig(out, dpi=DPI, bbox_inches="tight")
    return out


def _fit_title(fit: Mapping) -> str:
    metrics = fit.get("metrics") or {}
    shown = ", ".join(f"{k.upper()} {metrics[k]:.4g}" for k in ("rmse", "nrmse", "ncc") if metrics.get(k) is not None)
    params = ", ".join(f"{k} = {v:.3g}" for k, v in fit["params"].items())
    return f"fit {fit['model']}: {params}" + (f"\n{shown}" if shown else "")


#: Marker per incidence azimuth φi in the residual figure (colour: θi, on a colour scale).
PHI_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "h")


def _log_ticks(axis: Axis, lo: float, hi: float) -> None:
    """Labels a log axis can hold side by side: on a span of less than two decades matplotlib labels the minor
    ticks, and "3×10⁻¹" runs into "4×10⁻¹"; there the labels go at 1, 2 and 5 per decade (0.4 and 0.3 of a
    decade apart) and the minor ticks stay unlabelled, on wider spans at the decades."""
    axis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0) if np.log10(hi / lo) < 2 else (1.0,)))
    axis.set_major_formatter(LogFormatterSciNotation(labelOnlyBase=False, minor_thresholds=(np.inf, np.inf)))
    axis.set_minor_formatter(NullFormatter())


def residual_figure(ds: Dataset, fit: Mapping) -> Figure:
    """Fitted vs measured f_r and relative residuals vs θo, every series: colour = θi on a colour scale, marker =
    φi, so that sixteen series stay apart; the keys (colour bar, marker legend) sit outside the data."""
    model = _record_model(fit)
    wi, wo = ds.directions()
    f, u = ds["brdf_per_sr"], ds["u_brdf_per_sr"]
    f_fit = model(wi, wo)
    incidences = {int(s): ds.series_incidence_deg(int(s)) for s in np.unique(ds["series"])}
    thetas = [t for t, _ in incidences.values()]
    norm = Normalize(min(thetas), max(max(thetas), min(thetas) + 1.0))
    cmap = colormaps["plasma_r"].resampled(256)
    phis = sorted({_phi_shown(t, p) for t, p in incidences.values()})
    fig = Figure(figsize=(13, 6.0))
    ax_fit, ax_res = fig.add_axes((0.08, 0.24, 0.36, 0.6)), fig.add_axes((0.525, 0.24, 0.36, 0.6))
    residual = 100 * (f - f_fit) / f_fit
    for s, (theta_i, phi_i) in incidences.items():
        rows = ds["series"] == s
        marker = PHI_MARKERS[phis.index(_phi_shown(theta_i, phi_i)) % len(PHI_MARKERS)]
        bars = rows & _stated(u)
        ax_fit.errorbar(f[bars], f_fit[bars], xerr=u[bars], fmt="none", ecolor="0.65", lw=0.8, zorder=2)
        ax_res.errorbar(ds["theta_o_deg"][bars], residual[bars], yerr=100 * u[bars] / f_fit[bars], fmt="none",
                        ecolor="0.65", lw=0.8, zorder=2)
        for ax, x, y in ((ax_fit, f[rows], f_fit[rows]), (ax_res, ds["theta_o_deg"][rows], residual[rows])):
            ax.scatter(x, y, marker=marker, s=22, color=cmap(norm(theta_i)), edgecolors="k", linewidths=0.3,
                       zorder=3)
    both = np.concatenate([f, f_fit])
    lims = (0.7 * both[both > 0].min(), 1.4 * both.max())
    ax_fit.plot(lims, lims, color="0.3", lw=1, ls="--")
    ax_fit.set(xscale="log", yscale="log", xlim=lims, ylim=lims, xlabel="measured f_r [sr⁻¹]",
               ylabel="fitted f_r [sr⁻¹]", title="fitted against measured (± u); dashed: equal")
    for axis in (ax_fit.xaxis, ax_fit.yaxis):
        _log_ticks(axis, *lims)
    ax_res.axhline(0, color="0.3", lw=1)
    ax_res.set(xlabel="viewing angle θo [deg]", ylabel="(measured − fitted) / fitted [%]",
               title="relative residual against θo (± u)", xlim=(0, 90))
    for ax in (ax_fit, ax_res):
        ax.grid(True, which="both", alpha=0.3)
    fig.colorbar(ScalarMappable(norm, cmap), cax=fig.add_axes((0.9, 0.24, 0.015, 0.6)),
                 label="incidence θi [deg]")
    keys = [Line2D([], [], ls="none", marker=PHI_MARKERS[k % len(PHI_MARKERS)], color="0.35", markersize=7,
                   label=f"φi = {p:.1f}°") for k, p in enumerate(phis)]
    fig.legend(handles=keys, loc="lower center", bbox_to_anchor=(0.5, 0.0), ncol=min(len(keys), 6), fontsize=10,
               title="marker: incidence azimuth (colour: θi)", title_fontsize=10)
    fig.suptitle(f"{ds.sample_id()} — {_fit_title(fit)}", fontsize=12)
    return fig


def plot_residuals(ds: Dataset, fit: Mapping, out: Path) -> Path:
    """The residual figure, as a PNG."""
    residual_figure(ds, fit).savefig(out, dpi=DPI)
    return out


def plot_dataset(dataset: Dataset | str | os.PathLike, out_dir: str | os.PathLike,
                 fit: Mapping | None = None, *, plane_tol_deg: float = PLANE_TOL_DEG) -> list[Path]:
    """Write the figures of the module docstring into out_dir; returns their paths.

    out_dir is created; an existing file or non-empty folder is refused (DatasetError). The figures are
    drawn in a temporary folder renamed to out_dir when all are there (`new_folder`): a failure or an
    interrupt part-way leaves nothing, a kill at most the hidden temporary folder.
    """
    ds = dataset if isinstance(dataset, Dataset) else load(Path(dataset))
    if len(ds) == 0:
        raise DatasetError(f"{ds.path}: no measured point to plot")
    out_dir = Path(out_dir)
    require_new_output(out_dir, hint="choose another --out")
    model = None if fit is None else _record_model(fit)
    paths = []
    with new_folder(out_dir) as folder:
        for s in np.unique(ds["series"]).astype(int):
            stem = series_stem(s, *ds.series_incidence_deg(s))
            paths.append(plot_plane(ds, s, folder / f"plane_{stem}.png", model, plane_tol_deg))
            paths.append(plot_lobe(ds, s, folder / f"lobe_{stem}.png", model))
        if fit is not None:
            paths.append(plot_residuals(ds, fit, folder / "fit_residuals.png"))
    return [out_dir / p.name for p in paths]

