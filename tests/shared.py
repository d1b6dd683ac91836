"""Helpers that more than one test file uses (issue 32: shared test helpers in one module), so that no test file
imports another. A test file that imported another for one helper imported that file's tests and fixtures with it,
and found it only through pytest's default `prepend` import mode, which puts each test file's folder on sys.path
(under `--import-mode=importlib` the import fails; tests/browser had to add tests/monitor to sys.path itself).
This module is importable from every test folder (`pythonpath = ["tests"]`, as repo_paths and sim_worlds are), and
tests/test_structure.py fails when a test file imports another. A helper one test file uses stays in that file.
"""

from __future__ import annotations

import csv
import json
import math
import os
import socket
import types
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any, Literal, NoReturn, Union, get_args, get_origin

import annotated_types
import numpy as np
from hypothesis import strategies as st
from pydantic import BaseModel
from pymodbus.client import ModbusTcpClient

from repo_paths import CAMPAIGNS
from rig.acquisition.capture import PointCapture
from rig.acquisition.engine import Runner
from rig.acquisition.rows import Measurement, RowConstants
from rig.config.campaign import Capture, load_campaign, parse_campaign
from rig.config.capture import MODES
from rig.config.rigfile import RigConfig, simulated_rig
from rig.core.values import Window
from rig.data.dataset_format import BRDF_COLUMNS, FORMAT, csv_line
from rig.data.dataset_reader import Dataset
from rig.data.dataset_writer import DatasetWriter
from rig.monitor.folder import FolderFollower
from rig.physics import geometry as geo
from rig.physics.budget import lobe_view_u_deg
from rig.physics.geometry import BrdfAngles, sph_to_vec
from rig.planning.plan import build_plan
from rig.planning.points import PlannedPoint
from rig.simulators.rig import SimulatedRig

# ---------------------------------------------------------------------------------------------------------------------
# A run of the engine over the protocol rig (SimulatedRig), faults injected into its peers after a given point:
# tests/acquisition/test_runner.py, test_lamp_supply_outages.py.

def small_campaign(**extra):
    data = {
        "name": "small",
        "sample": {"id": "S", "simulated_brdf": {"model": "lambert", "params": {"kd": 0.5}}},
        "incidence": [{"phi": 0, "theta": [0, 60]}],
        "viewing": [{"centred_on": "normal", "theta": [10, 30], "phi": [0, 90, 180, 270]}],
        "lamp": {"warmup_min_s": 60},
        **extra,
    }
    return parse_campaign(data)


def run(tmp_path, campaign, camera_fault=None, inject=None):
    """Run `campaign`; `inject(peers, n_done)` is called after every point."""
    rig = RigConfig()
    plan = build_plan(campaign, rig)
    truth = campaign.sample.simulated_brdf
    writer = DatasetWriter(tmp_path / "ds", {"campaign": {"name": campaign.name}})
    with SimulatedRig(rig, truth.model, truth.params) as sim:
        if camera_fault is not None:
            sim.devices.camera = camera_fault(sim.devices.camera)
        progress = (lambda p: inject(sim.peers, p.done)) if inject else None
        runner = Runner(campaign, plan, sim.devices, writer, rig, progress=progress)
        try:
            status, error = runner.run(), None
        except Exception as exc:
            status, error = "raised", exc
        sim.world.clock.sleep(1.0)        # a stopped axis settles; one still running would not be done
        moving = [ax.name for ax in (*sim.devices.stage.axes, *sim.devices.arm.axes) if ax.is_moving()]
        lamp_on = sim.world.lamp.output_on
    writer.close()
    return status, error, runner, plan, lamp_on, moving


def rows(folder):
    with open(folder / "brdf.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def events(folder):
    return [json.loads(line) for line in (folder / "events.jsonl").read_text().splitlines()]


def at_point(n, action):
    """An inject callback that runs `action(peers)` once, after the n-th point.

    Progress is also reported on retries, with the same count: fire only once.
    """
    fired = []

    def inject(peers, done):
        if done == n and not fired:
            fired.append(done)
            action(peers)
    return inject


def suspenders_run(tmp_path, inject, campaign=None):
    """A run with a fault injected after point 6 and the given action when the run pauses: its events, its runner."""
    campaign = campaign or small_campaign(incidence=[{"phi": 0, "theta": [0, 30, 60]}])
    status, error, runner, plan, lamp_on, moving = run(tmp_path, campaign, inject=inject)
    assert status == "complete", error
    got = [r["point_id"] for r in rows(tmp_path / "ds")]
    assert sorted(got) == sorted(p.point_id for p in plan.points)        # each point once
    assert not lamp_on and not moving
    return events(tmp_path / "ds"), runner


# ---------------------------------------------------------------------------------------------------------------------
# One measured point and the row constants, against closed-form values (rig.acquisition.rows):
# tests/acquisition/test_rows.py, test_ledger.py.

KD = 0.5
THETA_I_DEG = 60.0
E_PERP_LX = 1000.0
#: A Lambertian sample lit at θi: L = kd/π · E⊥ cos θi, so f = L / (E⊥ cos θi) = kd/π.
LUMINANCE = KD / math.pi * E_PERP_LX * math.cos(math.radians(THETA_I_DEG))
CONSTANTS = RowConstants(angle_u_deg=0.1, lobe_view_u_deg=lobe_view_u_deg(0.1, 0.01), grazing_limit_deg=88.0,
                         calibration_u_rel=0.03)


def measurement(rig_time_s: float = 5.0) -> Measurement:
    """A point at θi = 60° whose ROI luminance is known to 1 % (noise 0.5 % of which dark 0.3 %)."""
    capture = PointCapture(
        luminance_cd_m2=LUMINANCE, u_luminance_cd_m2=0.01 * LUMINANCE, roi_std_cd_m2=0.02 * LUMINANCE,
        exposures_s=(0.01, 0.04), saturated_fraction=0.0, flags=(), image_cd_m2=None,
        roi_window=Window(10, 20, 30, 30), n_frames=4, u_noise_cd_m2=0.005 * LUMINANCE,
        u_dark_cd_m2=0.003 * LUMINANCE, u_texture_cd_m2=0.002 * LUMINANCE, capture_time_s=0.06, n_darks=2)
    point = PlannedPoint("s0-p1", 0, THETA_I_DEG, 0.0, 30.0, 180.0, (0.0, 60.0, 30.0, 180.0))
    angles = BrdfAngles(np.float64(THETA_I_DEG), np.float64(0.0), np.float64(30.0), np.float64(180.0))
    return Measurement(point, (0.0, 60.0, 30.0, 180.0), angles, capture, ("retried",), "2026-01-01T00:00:00Z",
                       rig_time_s)


# ---------------------------------------------------------------------------------------------------------------------
# Hand-written dataset folders (docs/dataset.md) that grow line by line as `rig run` writes them; their manifests
# carry campaigns/quick.yaml on the built-in simulated rig: tests/monitor/test_folder.py, test_monitor_connections.py,
# test_monitor_fuzz.py, test_monitor_hostile_files.py, test_monitor_runs.py, test_phase_file.py, test_server.py, and
# tests/browser/test_monitor_browser.py.

#: Wall seconds per rig second of the hand-written runs (a paced simulated rig).
WALL_PER_RIG = 0.1
START = datetime(2026, 1, 1, tzinfo=UTC)


def utc(rig_s: float) -> str:
    return (START + timedelta(seconds=rig_s * WALL_PER_RIG)).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def manifest(**changes) -> dict:
    return {"format": FORMAT, "format_version": "1.1", "created_utc": utc(0), "status": "running",
            "campaign": {"name": "quick", "content": load_campaign(CAMPAIGNS / "quick.yaml").model_dump(mode="json")},
            "sample": {"id": "RM1-sim"}, "rig": {"name": "simulated", "simulated": True,
                                                 "config": simulated_rig().model_dump(mode="json")},
            "software": {"name": "rig", "version": "0"}, "counts": {}, **changes}


def row(point_id: str, rig_s: float, theta_o: float = 30.0, phi_o: float = 180.0, flags: str = "") -> dict:
    """A brdf.csv row at θi = 30°, φi = 0° (the numbers are plausible, not simulated)."""
    values: dict[str, object] = {c: 0.001 for c in BRDF_COLUMNS}
    values.update(point_id=point_id, series=1, theta_i_deg=30.0, phi_i_deg=0.0, theta_o_deg=theta_o, phi_o_deg=phi_o,
                  brdf_per_sr=0.2, u_brdf_per_sr=0.002, exposures_s="0.01", flags=flags, time_utc=utc(rig_s),
                  rig_time_s=rig_s, filter_position=0, illuminance_interpolated=1)
    return values


class Folder:
    """A dataset folder written the way rig.data.dataset_writer writes one."""

    def __init__(self, path: Path, **manifest_changes):
        self.path = path
        path.mkdir()
        self.set_manifest(**manifest_changes)
        (path / "skipped.csv").write_text("point_id,theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,reason\n"
                                          "00-001,0,0,89,0,below_horizon\n00-002,0,0,88,0,beyond_max_view_theta\n"
                                          "00-003,0,0,87,0,below_horizon\n")
        self.append("brdf.csv", csv_line(BRDF_COLUMNS))
        (path / ".lock").write_text(f"pid {os.getpid()} host {socket.gethostname()}\n")   # the writer: alive
        self.follower = FolderFollower(path)

    def set_manifest(self, **changes) -> None:
        tmp = self.path / "dataset.json.tmp"
        tmp.write_text(json.dumps(manifest(**changes)))
        tmp.replace(self.path / "dataset.json")

    def append(self, name: str, text: str) -> None:
        with (self.path / name).open("a") as fh:
            fh.write(text)

    def event(self, kind: str, rig_s: float | None = None, **fields) -> None:
        record = {"time_utc": utc(rig_s or 0.0), "event": kind, **fields}
        if rig_s is not None:
            record["rig_time_s"] = rig_s
        self.append("events.jsonl", json.dumps(record) + "\n")

    def pending(self, point_id: str, rig_s: float) -> None:
        self.event("point_pending", row=row(point_id, rig_s))

    def row(self, point_id: str, rig_s: float, **kw) -> None:
        r = row(point_id, rig_s, **kw)
        self.append("brdf.csv", csv_line(r[c] for c in BRDF_COLUMNS))

    def look(self, since: int = 0) -> dict:
        self.follower.update()
        return self.follower.snapshot(since)


def warm(f: Folder) -> None:
    """Connected, lamp on at rig time 5 s, warm at 100 s, E⊥ read."""
    f.event("devices", identities={"lamp": "SM15K"}, simulated=True)
    f.event("lamp_on", 5.0, current_a=4.17, voltage_v=11.6)
    f.event("warmup_stable", 100.0, illuminance_lx=5000.0, change_rel=0.001, warmup_s=95.0, lamp_voltage_v=12.0)
    f.event("illuminance", 101.0, illuminance_normal_lx=4990.0, u_lx=4.0, readings=5)


# ---------------------------------------------------------------------------------------------------------------------
# A closed-form dataset for `rig predict` (a smooth isotropic BRDF on a grid of views):
# tests/analysis/test_predict.py, test_predict_plane.py.

THETA_I = [0.0, 20.0, 40.0, 60.0]
THETA_O = [0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0]
PHI_O = [0.0, 30.0, 60.0, 90.0, 120.0, 150.0, 180.0]


def smooth_brdf(theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg):
    """A smooth, isotropic, positive BRDF with a broad forward lobe (a few % change per 10°)."""
    wi = sph_to_vec(np.radians(theta_i_deg), np.radians(phi_i_deg))
    wo = sph_to_vec(np.radians(theta_o_deg), np.radians(phi_o_deg))
    mirror = wi * np.array([-1.0, -1.0, 1.0])
    return 0.2 * (1.0 + 0.5 * np.einsum("...i,...i->...", wo, mirror) ** 2)


def dataset(value=smooth_brdf, u_rel=0.01, phi_i=0.0, phi_o_deg=PHI_O) -> Dataset:
    ti, to, po = (a.ravel() for a in np.meshgrid(THETA_I, THETA_O, phi_o_deg, indexing="ij"))
    pi_ = np.full(ti.shape, phi_i)
    f = value(ti, pi_, to, po)
    columns = {"theta_i_deg": ti, "phi_i_deg": pi_, "theta_o_deg": to, "phi_o_deg": po, "brdf_per_sr": f,
               "u_brdf_per_sr": u_rel * f, "series": np.searchsorted(THETA_I, ti).astype(float)}
    n = len(f)
    return Dataset(path=Path("mem"), manifest={}, columns=columns, point_id=[f"p{k}" for k in range(n)],
                   flags=[()] * n, time_utc=[""] * n, skipped=[], header=list(columns))


# ---------------------------------------------------------------------------------------------------------------------
# Views around the incidence and the mirror direction, where a fit's lobes are: tests/analysis/test_fit.py,
# test_fit_global.py.

def views_around_lobes(offsets_deg, incidences=((0, 0), (40, 0), (60, 0), (70, 0), (80, 0), (85, 0), (80, 30)),
                       azimuths_deg=tuple(range(0, 360, 60))):
    """(wi, wo) pairs: rings of views at `offsets_deg` (and `azimuths_deg` about each centre) around the incidence and
    the mirror direction."""
    th, ph = np.meshgrid(np.radians(offsets_deg), np.radians(azimuths_deg), indexing="ij")
    wis, wos = [], []
    for theta_i, phi_i in incidences:
        wi = geo.sph_to_vec(np.radians(theta_i), np.radians(phi_i))
        for centre in (wi, geo.mirror_direction(wi)):
            wo = geo.centre_pattern(th.ravel(), ph.ravel(), centre)
            wo = wo[wo[:, 2] > np.cos(np.radians(88))]
            wis.append(np.broadcast_to(wi, wo.shape))
            wos.append(wo)
    return np.concatenate(wis), np.concatenate(wos)


# ---------------------------------------------------------------------------------------------------------------------
# Campaign field values drawn from the schema's own metadata (types, ge/gt/le/lt), so the draws follow the schema
# when a bound changes: tests/config/test_campaign_property.py, test_config_fuzz.py.

#: Fields whose allowed values are not in their type (validated by a function).
CHOICES = {(Capture, "mode"): MODES}


def _bounds(field) -> dict[str, float]:
    out = {}
    for m in field.metadata:
        for name in ("ge", "gt", "le", "lt"):
            if isinstance(m, getattr(annotated_types, name.capitalize())):
                out[name] = getattr(m, name)
    return out


def _base_type(annotation: Any) -> tuple[Any, bool]:
    """(the annotation without None, whether None is allowed)."""
    if get_origin(annotation) in (Union, types.UnionType):
        args = [a for a in get_args(annotation) if a is not type(None)]
        return args[0], len(args) < len(get_args(annotation))
    return annotation, False


def field_strategy(model: type[BaseModel], name: str) -> st.SearchStrategy:
    """Values of a field inside its declared bounds (cross-field rules aside)."""
    if (model, name) in CHOICES:
        return st.sampled_from(CHOICES[model, name])
    field = model.model_fields[name]
    kind, optional = _base_type(field.annotation)
    b = _bounds(field)
    if get_origin(kind) is Literal:
        strategy = st.sampled_from(get_args(kind))
    elif kind is bool:
        strategy = st.booleans()
    elif kind is int:
        lo = b.get("ge", b.get("gt", -10 ** 6 - 1) + 1)
        hi = b.get("le", b.get("lt", 10 ** 6 + 1) - 1)
        strategy = st.integers(lo, hi)
    elif kind is float:
        strategy = st.floats(min_value=b.get("ge", b.get("gt")), max_value=b.get("le", b.get("lt")),
                             exclude_min="gt" in b, exclude_max="lt" in b, allow_nan=False, allow_infinity=False)
    else:
        raise AssertionError(f"no strategy for {model.__name__}.{name}: {field.annotation}")
    return st.one_of(st.none(), strategy) if optional else strategy


# ---------------------------------------------------------------------------------------------------------------------
# The drivers' in-memory protocol replay (PyMeasure's `expected_protocol`): the fixture is in tests/drivers/conftest.py
# (its docstring says how a script is written); test_zaber.py builds a replay of its own for a port that hands out
# a reply line by line.

Exchange = tuple[bytes, bytes | None]


@dataclass
class Replay:
    """The script, and what the driver did with it (`written`: each request with the rig time it came)."""

    exchanges: list[Exchange]
    now: Callable[[], float] = lambda: 0.0
    written: list[tuple[bytes, float]] = field(default_factory=list)
    #: The port's timeout (s) at each read: what the driver was prepared to wait for each reply.
    read_timeouts: list[float | None] = field(default_factory=list)
    opens: int = 0
    _reply: bytes | None = None
    _problems: list[str] = field(default_factory=list)

    # -- the script ------------------------------------------------------------------------------
    def request(self, data: bytes) -> bytes | None:
        """Take the next exchange for `data`; its reply, or fail the test."""
        step = len(self.written)
        self.written.append((data, self.now()))
        if step >= len(self.exchanges):
            self._fail(f"unexpected request #{step}: {data!r} (the script has {len(self.exchanges)})")
        expected, reply = self.exchanges[step]
        if data != expected:
            self._fail(f"request #{step}: expected {expected!r}, got {data!r}")
        return reply

    def _fail(self, problem: str) -> NoReturn:
        self._problems.append(problem)
        raise AssertionError(problem)

    def check_complete(self) -> None:
        assert not self._problems, self._problems
        missing = self.exchanges[len(self.written):]
        assert not missing, f"exchanges the driver never made: {missing}"

    # -- a pyserial port ---------------------------------------------------------------------------
    def open_port(self, url: str, *, baudrate: int, timeout: float, write_timeout: float) -> ReplayPort:
        self.opens += 1
        return ReplayPort(self, timeout)

    # -- a pymodbus client -------------------------------------------------------------------------
    def open_client(self, url: str, timeout_s: float) -> ReplayModbusClient:
        return ReplayModbusClient(self, timeout_s)


class ReplayPort:
    """A pyserial port whose far end is the script: one write is one request."""

    def __init__(self, replay: Replay, timeout: float | None = None):
        self.replay = replay
        self.timeout = timeout
        self.is_open = True
        self._pending: bytes | None = None

    def write(self, data: bytes, /) -> int:
        assert self.is_open, f"write {data!r} on a closed port"
        self._pending = self.replay.request(data)
        return len(data)

    def flush(self) -> None:
        pass

    def reset_input_buffer(self) -> None:
        pass

    def read_until(self, expected: bytes = b"\n", size: int | None = None) -> bytes:
        self.replay.read_timeouts.append(self.timeout)
        if self._pending is None:
            self.replay._fail(f"read after {self.replay.written[-1][0]!r}, which has no reply in the script"
                              if self.replay.written else "read before any request")
        reply, self._pending = self._pending, None
        return reply or b""

    def close(self) -> None:
        self.is_open = False


class ReplayModbusClient(ModbusTcpClient):
    """pymodbus' Modbus/TCP client with the script in place of its socket; replies get the request's header."""

    def __init__(self, replay: Replay, timeout_s: float):
        super().__init__("replay", timeout=timeout_s, retries=0)
        self.replay = replay
        self._open = False
        self._incoming = b""

    @property
    def connected(self) -> bool:
        return self._open

    def connect(self) -> bool:
        if not self._open:
            self.replay.opens += 1
        self._open = True
        return True

    def close(self) -> None:
        self._open = False

    def send(self, request: bytes, addr: tuple | None = None) -> int:
        header, pdu = request[:7], request[7:]
        reply = self.replay.request(pdu)
        if reply is not None:
            self._incoming = header[:4] + (len(reply) + 1).to_bytes(2, "big") + header[6:7] + reply
        return len(request)

    def recv(self, size: int | None) -> bytes:
        data, self._incoming = self._incoming, b""
        return data


# ---------------------------------------------------------------------------------------------------------------------
# Reply timeouts of the drivers' integration tests over real ptys and sockets (tests/drivers/test_*_integration.py).

#: Where every reply comes: long, so that a reply slowed by a loaded machine (CI's two cores under xdist) is not
#: taken for a lost one; a retry event would break those tests' exact event lists. It costs nothing: a reply that
#: comes ends the wait.
ANSWERED_S = 10.0
#: Where replies are lost on purpose (an injected silence or a cut-short reply): short, so that each lost reply costs
#: little wall time.
SILENCE_S = 0.2


# ---------------------------------------------------------------------------------------------------------------------
# Driver byte exchanges, the driver's in-memory replays and the rebuilt peer's answers alike (named by device: each
# device has its CONNECT). Provenance of the bytes is given per device.

# P-9710 optometer: tests/drivers/test_p9710.py, test_p9710_integration.py. The manual: P-9710 Operating Manual V1.20,
# §15 Remote Interface (the bare LF that acknowledges a command without answer, `SN` p × 0.1 ms, `MA`/`GR` answers,
# chained commands), via github matusm/Bev.Instruments.P9710.Detector doc/GO_P-9710_RemoteInterface.pdf; a real
# firmware 5.6 unit: `GI`→`P9710 V5.6`, `TT`→`1875`, `GK`→`VL__` (github matusm/Bev.Instruments.P9710 P9710.cs, as
# logged in matusm/Bev.Instruments.P9710.Detector doc/BruteForce.txt), LF framing from P9710.cs.

#: Acknowledge characters off (manual §15.3.9 `TD0`), a real unit's identity exchanges (captured), then autorange
#: on and 0.2 s integration (manual), each setting acked by a bare LF.
P9710_TD0 = (b"TD0\n", b"\n")
P9710_CONNECT = [P9710_TD0, (b"GI\n", b"P9710 V5.6\n"), (b"TT\n", b"1875\n"), (b"GK\n", b"VL__\n"), (b"SB1\n", b"\n"),
                 (b"SN2000\n", b"\n")]
P9710_READING = (b"MA;GR\n", b"+1.2345E-06;3\n")

# Delta SM15K lamp supply (SCPI over TCP): tests/drivers/test_delta_sm.py, test_delta_sm_integration.py. Replies
# follow the examples of the manual "Ethernet & Sequencer Programming SM15K", rev. July 2021 (§5.1.1 `*IDN?`,
# §5.2.2 maxima as integers, §5.2.7 `14.0000`, §5.6.7 `0,None`, §5.6.10 watchdog `-1`), via github
# keklikyusuf/DeltaElektronika.

DELTA_SM_IDN = "DELTA ELEKTRONIKA BV,SM500-CP-90,000010207248,H0_P0150,0"      # manual §5.1.1
DELTA_SM_OK = ("SYSTem:ERRor?", "0,None")
DELTA_SM_CONNECT = [("*IDN?", DELTA_SM_IDN),
                    ("SYSTem:COMmunicate:WATchdog?", "-1"),                   # off after power-on
                    ("SOURce:CURrent:MAXimum?", "90"),
                    ("SOURce:VOLtage:MAXimum?", "500"),
                    ("*CLS", None), DELTA_SM_OK,                              # the session's settings (_configure)
                    ("SYSTem:REMote:CV REMote", None), DELTA_SM_OK,
                    ("SYSTem:REMote:CC REMote", None), DELTA_SM_OK,
                    ("SYSTem:LIMits:CURrent 4.6000,ON", None), DELTA_SM_OK,
                    ("SYSTem:LIMits:CURrent?", "4.6000"),
                    ("SYSTem:LIMits:VOLtage 14.0000,ON", None), DELTA_SM_OK,  # the lamp's limit, not the supply's 500 V
                    ("SYSTem:LIMits:VOLtage?", "14.0000"),
                    ("SOURce:VOLtage 14.0000", None), DELTA_SM_OK,
                    ("SYSTem:COMmunicate:WATchdog SET,1000", None), DELTA_SM_OK]
DELTA_SM_CLOSE = [("SYSTem:COMmunicate:WATchdog STOP", None), DELTA_SM_OK,
                  ("SYSTem:REMote:CV LOCal", None), DELTA_SM_OK,
                  ("SYSTem:REMote:CC LOCal", None), DELTA_SM_OK]

# Zaber ASCII chain: tests/drivers/test_zaber.py, test_zaber_integration.py. The Zaber ASCII protocol manual
# (zaber.com/protocol-manual: `/d a command[:LRC]`, replies `@dd a OK|RJ BUSY|IDLE FLAG data` + CRLF, checksums on
# replies) and the A/X-series unit conversions (maxspeed data = µsteps/s × 1.6384, accel data = µsteps/s² × 1.6384 /
# 10000); no real captures were found.
#: Axis 1 of device 1 (1 536 000 µsteps per turn) once homed, its speed and acceleration already the rig file's
#: (15 °/s → 104858, 30 °/s² → 21): nothing is written to its flash (replies with their checksums, as a device with
#: checksums on sends them).
ZABER_CONNECT = [
    (b"/1 1 get limit.cycle.dist:BF\n", b"@01 1 OK IDLE -- 1536000:5D\r\n"),
    (b"/1 1 get maxspeed:A7\n", b"@01 1 OK IDLE -- 104858:82\r\n"),
    (b"/1 1 get accel:06\n", b"@01 1 OK IDLE -- 21:59\r\n"),
    (b"/1 1 warnings:F5\n", b"@01 1 OK IDLE -- 00:5C\r\n"),
]
