"""ALTA text BRDF files (Belcour, Pacanowski et al.): reader, writer, conversion to rig angles.

Format (the ALTA library's text format, github.com/belcour/alta): header lines `#KEY value` (`#DIM N P`,
`#PARAM_IN`, `#PARAM_OUT`, `#VS 0|1|2`, free keys such as `#SAMPLE`), comment
lines `# text`, then one whitespace-separated row per sample: N inputs, P
outputs, then the vertical segment of the first output only. Angles are radians.

Vertical segments (`#VS`), as ALTA's loader reads them (sources/core/data_storage.cpp,
`read_confidence_interval`, since ALTA commit 302c046 of 2017-07-25; docs/alta.md):
- `#VS 0`: no column; ALTA then gives every point the segment [y − dt, y + dt] of
  its `--dt` option (default 0.1, absolute).
- `#VS 1`: one column d, the segment [y − d, y + d].
- `#VS 2`: two columns d₋ d₊, distances below and above y: the segment
  [y − d₋, y + d₊] (before that commit ALTA read them as absolute bounds; we
  follow the current loader).
ALTA's fitters take the segment as a hard bound on the fitted function, so its
half-width is a coverage interval k·u, not a standard uncertainty. rig writes the
k it used in the comment line `# rig coverage_k=<k>: ...` (`coverage_comment`);
reading, u = half-width / k with that k, else with k = 1 (said in the notes).
A `#KEY` line after the first data row is skipped, as ALTA's loader skips every
`#` line there, and a note names it.

Conventions of the conversion to rig angles (docs/geometry.md):
- `SPHERICAL_TL_PL_TV_PV` = [θL, φL, θV, φV]: the light is our incident direction
  ωi, the view our viewing direction ωo; both point away from the surface and
  use φ = atan2(y, x) like ours, so the angles carry over unchanged.
- `ISOTROPIC_TL_TV_PROJ_DPHI` = [θL, θV·cos Δφ, θV·sin Δφ]: ALTA's own conversion
  (params::to_cartesian) puts the light at φL = 0 and the view at
  φV = atan2(θV·sin Δφ, θV·cos Δφ), i.e. Δφ = φV − φL. We keep that: φi = 0,
  φo = Δφ. Retroreflection (ωo = ωi) is then Δφ = 0, at (+θL, 0) in the
  projected plane, and the mirror direction at (−θL, 0). Checked on the CEA
  tapes (tests/data/test_import.py): the side θV·cos Δφ ≥ 0 holds the broad
  retroreflection lobe and the instrument's blind ring around exact
  retroreflection; the other side holds a narrow specular peak of the top film.
- `INV_STERADIAN_COSINE_FACTOR` (f·cos θV) is divided by cos θV; points with
  θV > `COSINE_FACTOR_MAX_THETA_DEG` are not converted (reason
  `cosine_factor_near_horizon`): the division would amplify their noise more
  than 57-fold and is infinite at the horizon.
- Points with θL or θV ≥ 90° (within `HORIZON_TOL_DEG`) are not converted (reason
  `below_horizon`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rig.physics.geometry import BrdfAngles, sph_to_vec, vec_to_sph, wrap_360

#: Input parametrizations ALTA knows, with their number of input dimensions (params.cpp).
PARAM_IN_DIMS = {
    "COS_TH": 1, "COS_TK": 1, "COS_TLV": 1, "COS_TLR": 1,
    "RUSIN_TH_TD": 2, "COS_TH_TD": 2, "ISOTROPIC_TV_PROJ_DPHI": 2, "STARK_2D": 2, "NEUMANN_2D": 2,
    "RUSIN_TH_PH_TD": 3, "RUSIN_TH_TD_PD": 3, "ISOTROPIC_TV_TL_DPHI": 3, "RUSIN_VH": 3, "SCHLICK_VK": 3,
    "ISOTROPIC_TL_TV_PROJ_DPHI": 3, "SCHLICK_TL_TK_PROJ_DPHI": 3, "RETRO_TL_TVL_PROJ_DPHI": 3,
    "STARK_3D": 3, "NEUMANN_3D": 3,
    "RUSIN_TH_PH_TD_PD": 4, "SPHERICAL_TL_PL_TV_PV": 4, "STEREOGRAPHIC": 4,
    "CARTESIAN": 6,
}
PARAM_OUTS = ("INV_STERADIAN", "INV_STERADIAN_COSINE_FACTOR", "ENERGY", "RGB_COLOR", "XYZ_COLOR")
#: The parametrizations `to_rig` converts.
CONVERTIBLE_IN = ("SPHERICAL_TL_PL_TV_PV", "ISOTROPIC_TL_TV_PROJ_DPHI")
CONVERTIBLE_OUT = ("INV_STERADIAN", "INV_STERADIAN_COSINE_FACTOR")
#: Angles this close to 90° count as on the horizon (the files give π/2 rounded through cos/sin).
HORIZON_TOL_DEG = 1e-6
#: Beyond this viewing angle f·cos θV is not divided by cos θV (amplification > 57×).
COSINE_FACTOR_MAX_THETA_DEG = 89.0
_STRUCTURAL_KEYS = ("DIM", "PARAM_IN", "PARAM_OUT", "VS")
CONVERSION_SKIP_REASONS = {
    "below_horizon": "light or view at or below the sample plane (θ ≥ 90°)",
    "cosine_factor_near_horizon": f"f·cos θV given with θV > {COSINE_FACTOR_MAX_THETA_DEG:g}°: "
                                  "dividing by cos θV would amplify the noise more than 57-fold",
}


#: The comment by which rig states the coverage factor of the segment columns (`coverage_comment`).
COVERAGE_COMMENT = re.compile(r"rig coverage_k=(\S+?):")


def coverage_comment(coverage_k: float) -> str:
    """The comment line (without `# `) that states the k of the segment columns; `read_alta` finds it."""
    return (f"rig coverage_k={coverage_k!r}: the vertical segment of f is ±{coverage_k:g}·u(f), "
            "u the standard uncertainty (ALTA's fitters take it as a hard bound)")


class AltaError(ValueError):
    """A malformed or unsupported ALTA file; the message names the file (and line)."""


@dataclass(frozen=True)
class AltaData:
    """An ALTA text file in memory; `x` inputs (M, N), `y` outputs (M, P), `ci` segment columns (M, VS).

    `coverage_k`: the k of a rig coverage comment, None without one. `notes`: what the reader
    tolerated (e.g. a `#KEY` line after the data, skipped).
    """

    path: Path
    header: dict[str, str]
    comments: list[str]
    n_in: int
    n_out: int
    param_in: str | None
    param_out: str | None
    vs: int
    x: np.ndarray
    y: np.ndarray
    ci: np.ndarray
    line: np.ndarray          # source line number (1-based) of each row
    coverage_k: float | None = None
    notes: tuple[str, ...] = ()

    def __len__(self) -> int:
        return len(self.x)


def _header_int(path: Path, lineno: int, key: str, value: str, count: int) -> list[int]:
    parts = value.split()
    try:
        numbers = [int(p) for p in parts]
    except ValueError:
        numbers = []
    if len(numbers) != count or any(n < 0 for n in numbers):
        raise AltaError(f"{path}:{lineno}: #{key} needs {count} non-negative integer(s), got {value!r}")
    return numbers


def _parse_header_line(text: str, header: dict[str, str], comments: list[str]) -> str | None:
    """Store a `#KEY value` line in `header` (returning KEY) or a `# comment` in `comments`."""
    body = text[1:]
    if not body.strip() or body[0].isspace():
        comments.append(body.strip())
        return None
    key, *value = body.split(None, 1)
    header[key] = value[0].strip() if value else ""
    return key


def _parse_row(path: Path, lineno: int, text: str, n_cols: int) -> list[float]:
    tokens = text.split()
    if len(tokens) != n_cols:
        raise AltaError(f"{path}:{lineno}: expected {n_cols} columns (from #DIM and #VS), got {len(tokens)}")
    values = []
    for token in tokens:
        try:
            values.append(float(token))
        except ValueError:
            raise AltaError(f"{path}:{lineno}: not a number: {token!r}") from None
    if not all(math.isfinite(v) for v in values):
        raise AltaError(f"{path}:{lineno}: non-finite value in {text!r}")
    return values


def _check_header(path: Path, header: Mapping[str, str], header_line: Mapping[str, int]) -> tuple[int, int, int]:
    if "DIM" not in header:
        raise AltaError(f"{path}: no #DIM line before the data (e.g. '#DIM 4 1')")
    n_in, n_out = _header_int(path, header_line["DIM"], "DIM", header["DIM"], 2)
    if n_in == 0 or n_out == 0:
        raise AltaError(f"{path}:{header_line['DIM']}: #DIM needs positive dimensions, got {header['DIM']!r}")
    vs = _header_int(path, header_line["VS"], "VS", header["VS"], 1)[0] if "VS" in header else 0
    if vs > 2:
        raise AltaError(f"{path}:{header_line['VS']}: #VS must be 0, 1 or 2, got {vs}")
    param_in = header.get("PARAM_IN")
    if param_in is not None:
        if param_in not in PARAM_IN_DIMS:
            raise AltaError(f"{path}:{header_line['PARAM_IN']}: unknown #PARAM_IN {param_in!r}")
        if PARAM_IN_DIMS[param_in] != n_in:
            raise AltaError(f"{path}:{header_line['DIM']}: #DIM {n_in} {n_out} but {param_in} has "
                            f"{PARAM_IN_DIMS[param_in]} inputs")
    param_out = header.get("PARAM_OUT")
    if param_out is not None and param_out not in PARAM_OUTS:
        raise AltaError(f"{path}:{header_line['PARAM_OUT']}: unknown #PARAM_OUT {param_out!r}")
    return n_in, n_out, vs


def _coverage_k(path: Path, comments: Iterable[str]) -> float | None:
    """The k of the first rig coverage comment; AltaError if it is not a positive finite number."""
    for comment in comments:
        match = COVERAGE_COMMENT.match(comment)
        if match:
            try:
                k = float(match.group(1))
            except ValueError:
                k = math.nan
            if not (math.isfinite(k) and k > 0):
                raise AltaError(f"{path}: coverage comment {comment[:60]!r} does not give a positive k")
            return k
    return None


def read_alta(path: str | Path) -> AltaData:
    """Read an ALTA text file; raises AltaError naming file and line for malformed input.

    The header ends at the first line that is neither blank nor starts with `#`. After it,
    `# comment` lines may be mixed with the rows, and `#KEY value` lines are skipped with a
    note, as ALTA's loader does (a #KEY there does not change the header).
    """
    path = Path(path)
    try:
        lines = [(n, t.strip()) for n, t in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1)]
    except UnicodeDecodeError as exc:
        raise AltaError(f"{path}: not a text file ({exc.reason})") from None
    start = next((i for i, (_, t) in enumerate(lines) if t and not t.startswith("#")), len(lines))
    header: dict[str, str] = {}
    header_line: dict[str, int] = {}
    comments: list[str] = []
    for lineno, text in lines[:start]:
        key = _parse_header_line(text, header, comments) if text else None
        if key in _STRUCTURAL_KEYS and key in header_line:
            raise AltaError(f"{path}:{lineno}: #{key} given twice (first on line {header_line[key]})")
        if key is not None:
            header_line[key] = lineno
    n_in, n_out, vs = _check_header(path, header, header_line)
    rows: list[list[float]] = []
    row_lines: list[int] = []
    notes: list[str] = []
    for lineno, text in lines[start:]:
        if text.startswith("#"):
            if _parse_header_line(text, {}, comments) is not None:
                notes.append(f"line {lineno}: {text[:60]!r} after the data skipped, as ALTA's loader does")
        elif text:
            rows.append(_parse_row(path, lineno, text, n_in + n_out + vs))
            row_lines.append(lineno)
    table = np.array(rows, dtype=float).reshape(len(rows), n_in + n_out + vs)
    return AltaData(path=path, header=header, comments=comments, n_in=n_in, n_out=n_out,
                    param_in=header.get("PARAM_IN"), param_out=header.get("PARAM_OUT"), vs=vs,
                    x=table[:, :n_in], y=table[:, n_in:n_in + n_out], ci=table[:, n_in + n_out:],
                    line=np.array(row_lines, dtype=int), coverage_k=_coverage_k(path, comments), notes=tuple(notes))


def _number(value: float | np.ndarray) -> str:
    """Shortest text that reads back to the same double."""
    return repr(float(value))


def write_alta(path: str | Path, x: np.ndarray, y: np.ndarray, *, param_in: str, param_out: str,
               ci: np.ndarray | None = None, coverage_k: float | None = None,
               header: Mapping[str, str] | None = None, comments: Iterable[str] = ()) -> Path:
    """Write an ALTA text file; values at full double precision so the file reads back exactly.

    `ci`: the vertical segment of the first output as ALTA reads it: (M,) half-widths d
    (#VS 1, [y − d, y + d]) or (M, 2) distances below and above y (#VS 2); None for #VS 0.
    `coverage_k`: the k of those columns (half-width = k·u), stated in a comment line that
    `read_alta` reads back; None writes no such line. `header`: extra `#KEY value` lines (e.g. SAMPLE).
    """
    x = np.atleast_2d(np.asarray(x, float))
    y = np.asarray(y, float).reshape(len(x), -1)
    ci = np.empty((len(x), 0)) if ci is None else np.asarray(ci, float).reshape(len(x), -1)
    if PARAM_IN_DIMS.get(param_in) != x.shape[1]:
        raise ValueError(f"{param_in} does not take {x.shape[1]} inputs")
    if param_out not in PARAM_OUTS or ci.shape[1] > 2:
        raise ValueError(f"bad PARAM_OUT {param_out!r} or {ci.shape[1]} confidence columns")
    table = np.hstack([x, y, ci])
    if not np.all(np.isfinite(table)):
        raise ValueError("refusing to write non-finite values to an ALTA file")
    if np.any(ci < 0):
        raise ValueError("refusing to write a negative vertical-segment half-width or distance")
    if coverage_k is not None:
        if not ci.shape[1]:
            raise ValueError("a coverage factor k without vertical-segment columns (#VS 0)")
        comments = [*comments, coverage_comment(coverage_k)]
    lines = [f"# {c}" for c in comments]
    lines += [f"#{k} {v}" for k, v in (header or {}).items()]
    lines += [f"#DIM {x.shape[1]} {y.shape[1]}", f"#PARAM_IN {param_in}", f"#PARAM_OUT {param_out}",
              f"#VS {ci.shape[1]}"]
    lines += [" ".join(_number(v) for v in row) for row in table]
    path = Path(path)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


@dataclass(frozen=True)
class RigPoints:
    """ALTA samples in rig conventions: angles (degrees), f_r, u(f_r) and why a point is left out."""

    angles: BrdfAngles
    brdf: np.ndarray
    u_brdf: np.ndarray | None          # None when the file has no confidence columns (#VS 0)
    reason: np.ndarray                 # "" for converted points, else a key of CONVERSION_SKIP_REASONS
    param_out: str                     # the output parametrization used (file's or assumed)
    notes: list[str]


def _directions(param_in: str, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(ωi, ωo) unit vectors and the azimuths to keep at the poles, radians."""
    if param_in == "SPHERICAL_TL_PL_TV_PV":
        return sph_to_vec(x[:, 0], x[:, 1]), sph_to_vec(x[:, 2], x[:, 3]), x[:, 1], x[:, 3]
    if param_in == "ISOTROPIC_TL_TV_PROJ_DPHI":
        theta_v = np.hypot(x[:, 1], x[:, 2])
        dphi = np.arctan2(x[:, 2], x[:, 1])
        zero = np.zeros(len(x))
        return sph_to_vec(x[:, 0], zero), sph_to_vec(theta_v, dphi), zero, dphi
    raise ValueError(f"no conversion from {param_in}")


def _uncertainty(data: AltaData) -> np.ndarray | None:
    """u of the first output: the segment's half-width (#VS 1: d; #VS 2: (d₋ + d₊)/2) divided by k."""
    if data.vs == 0:
        return None
    return data.ci.mean(axis=1) / (data.coverage_k or 1.0)


def _uncertainty_note(data: AltaData) -> str:
    half_width = {1: "the ± column", 2: "half the segment [y − d₋, y + d₊]"}[data.vs]
    if data.coverage_k is None:
        return (f"u(f) = {half_width} (#VS {data.vs}), taken as k = 1: the file does not say which "
                "coverage factor its segments have")
    return f"u(f) = {half_width} (#VS {data.vs}) / k, k = {data.coverage_k:g} from the file's rig coverage comment"


def to_rig(data: AltaData, *, assume_param_out: str | None = None) -> RigPoints:
    """Convert the samples to rig angles and f_r (conventions in the module docstring).

    `assume_param_out` is used only when the file has no #PARAM_OUT line (and is
    then required); the choice is recorded in `notes`.
    """
    where = str(data.path)
    if data.param_in not in CONVERTIBLE_IN:
        raise AltaError(f"{where}: #PARAM_IN {data.param_in} cannot be imported "
                        f"(supported: {', '.join(CONVERTIBLE_IN)})")
    if data.n_out != 1:
        raise AltaError(f"{where}: {data.n_out} outputs; only single-channel BRDF files can be imported")
    notes = [*data.notes, f"angles from {data.param_in} (radians) to rig degrees; "
             + ("light at φi = 0, view φo = Δφ (retroreflection at Δφ = 0)"
                if data.param_in == "ISOTROPIC_TL_TV_PROJ_DPHI" else "angles carried over unchanged")]
    if data.vs:
        notes.append(_uncertainty_note(data))
    param_out = data.param_out
    if param_out is None:
        if assume_param_out is None:
            raise AltaError(f"{where}: no #PARAM_OUT line; say which output it holds")
        param_out = assume_param_out
        notes.append(f"no #PARAM_OUT in the file: assumed {param_out}")
    if param_out not in CONVERTIBLE_OUT:
        raise AltaError(f"{where}: #PARAM_OUT {param_out} cannot be imported "
                        f"(supported: {', '.join(CONVERTIBLE_OUT)})")
    _refuse_impossible_values(data)
    wi, wo, phi_i_pole, phi_o_pole = _directions(data.param_in, data.x)
    theta_i, phi_i = vec_to_sph(wi, phi_i_pole)
    theta_o, phi_o = vec_to_sph(wo, phi_o_pole)
    angles = BrdfAngles(np.degrees(theta_i), wrap_360(np.degrees(phi_i)),
                        np.degrees(theta_o), wrap_360(np.degrees(phi_o)))
    horizon = 90.0 - HORIZON_TOL_DEG
    reason = np.where((angles.theta_i_deg >= horizon) | (angles.theta_o_deg >= horizon), "below_horizon", "")
    brdf, u = data.y[:, 0].copy(), _uncertainty(data)
    if param_out == "INV_STERADIAN_COSINE_FACTOR":
        grazing = (angles.theta_o_deg > COSINE_FACTOR_MAX_THETA_DEG) & (reason == "")
        reason = np.where(grazing, "cosine_factor_near_horizon", reason)
        cos_o = np.where(reason == "", np.cos(theta_o), 1.0)
        brdf /= cos_o
        u = None if u is None else u / cos_o
        notes.append(f"f·cos θV divided by cos θV; points with θV > {COSINE_FACTOR_MAX_THETA_DEG:g}° left out")
    overflow = (reason == "") & ~(np.isfinite(brdf) & np.isfinite(u if u is not None else brdf))
    if overflow.any():
        k = int(np.flatnonzero(overflow)[0])
        raise AltaError(f"{where}:{data.line[k]}: value {_number(data.y[k, 0])} gives a BRDF or uncertainty too large "
                        "for a double")
    return RigPoints(angles=angles, brdf=brdf, u_brdf=u, reason=reason,
                     param_out=param_out, notes=notes)


def _refuse_impossible_values(data: AltaData) -> None:
    """AltaError naming the line of a negative BRDF or a negative segment half-width or distance:
    a broken file (or, for #VS 2, one written with the absolute bounds of ALTA before 2017),
    not noise whose absolute value to take."""
    f = data.y[:, 0]
    checks = [(f < 0, lambda k: f"BRDF value {_number(f[k])} is negative")]
    if data.vs == 1:
        checks.append((data.ci[:, 0] < 0, lambda k: f"uncertainty ±{_number(data.ci[k, 0])} is negative"))
    if data.vs == 2:
        checks.append((np.any(data.ci < 0, axis=1), lambda k: f"segment distances below/above y "
                       f"{_number(data.ci[k, 0])} {_number(data.ci[k, 1])}: one is negative (#VS 2)"))
    for bad, say in checks:
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise AltaError(f"{data.path}:{data.line[k]}: {say(k)}; nothing was imported")
