"""The public C# P-9710 client's dialogue against our simulated meter, over a pseudo-terminal.

github matusm/Bev.Instruments.P9710 (`P9710.cs`, MIT) is a lab's own client of a real P-9710 (firmware
5.6): a serial port opened for each query (9600 8N1, LF line ends), one command line written, one
answer line read, the port closed again. `PublicClient` below is our Python transliteration of the
dialogue it documents (which commands in which order, how answers are parsed: .NET's
`double.TryParse(..., NumberStyles.Any, InvariantCulture)` and `int.TryParse`), written from that
behaviour, not copied. Against a real unit the client produced (the repository's doc/dumpDetector1.txt,
github matusm/Bev.Instruments.P9710.Detector) `InstrumentID: P9710-521 V5.6 SN:1875 @ COM5` and
`DetectorID: VL__ SN:52365 (GO2000)`; our peer must give the same, and every answer must have the form
the manual (V1.20 §15.3) gives it.
"""

from __future__ import annotations

import math
import re

import pytest
import serial

from rig.config.rigfile import MeterConfig, RigConfig, SimulationConfig
from rig.physics.brdf_models import get_model
from rig.simulators.p9710_peer import P9710Peer
from rig.simulators.world import SimWorld

CAL = 1.0e9
#: P9710.cs waits 100 ms after closing the port and after each query; the pty needs no wait.
WAIT_ON_CLOSE_S = 0.0
#: P9710.cs reads with .NET's default (no timeout, it would wait for ever); a test must not.
READ_TIMEOUT_S = 2.0
#: `MeasurementRange` of P9710.cs: the meter's range r is `Range{r + 3:02d}` (10^-(r+3) A/V).
RANGE_NAMES = {str(r): f"Range{r + 3:02d}" for r in range(8)}
_DOTNET_NUMBER = re.compile(r"\s*[+-]?(\d[\d,]*\.?\d*|\.\d+)([eE][+-]?\d+)?\s*")

#: The manual's answer formats (§15.3), by command: what every answer in the dialogue must match.
NUMBER = r"[+-]\d\.\d{4}E[+-]\d\d"
MANUAL_FORMS = {
    "GI": r"P-?9710 V?\d+\.\d+",       # manual `P-9710 x.x`; a 5.6 unit `P9710 V5.6`
    "TF": r"\d{1,4}", "TT": r"\d{1,4}", "GK": r"\S{1,6}", "GU": r"\S+", "MB": r"\d{1,3}%",
    "GC": r"\d{1,3}", "GR": r"[0-7]",
    "GS4": r"[+-]?\d\.\d{4}E[+-]?\d\d",  # manual `x.xxxxExx`
    "MA": NUMBER, "MV": NUMBER,
    "SB": "", "SR": "",                 # a setting: the bare LF
}


def parse_double(text: str) -> float:
    """.NET's `double.TryParse(s, NumberStyles.Any, InvariantCulture)`, NaN where it fails (a `%`, `?16`)."""
    return float(text.replace(",", "")) if _DOTNET_NUMBER.fullmatch(text) else math.nan


def parse_int(text: str) -> int:
    """.NET's `int.TryParse`: 0 where it fails."""
    return int(text) if re.fullmatch(r"\s*[+-]?\d+\s*", text) else 0


class PublicClient:
    """The dialogue of P9710.cs: every query on a freshly opened port; `dialogue` records (command, answer)."""

    def __init__(self, port_name: str):
        self.device_port = port_name.strip()
        self.dialogue: list[tuple[str, str]] = []
        self.select_auto_range()                # the constructor's one setting: autorange on

    def query(self, command: str) -> str:
        """Open, WriteLine, ReadLine, close; "???" when the reply does not come (P9710.cs swallows the error)."""
        answer = "???"
        with serial.Serial(self.device_port, 9600, bytesize=8, parity="N", stopbits=1,
                           timeout=READ_TIMEOUT_S) as port:
            port.write(command.encode("ascii") + b"\n")
            line = port.read_until(b"\n")
            if line.endswith(b"\n"):
                answer = line[:-1].decode("ascii")
        self.dialogue.append((command, answer))
        return answer

    # -- the instrument --------------------------------------------------------------------------
    def _software_version(self) -> list[str]:
        tokens = self.query("GI").split(" ")
        return tokens if len(tokens) >= 2 else ["?", "?"]

    @property
    def instrument_type(self) -> str:
        return f"{self._software_version()[0]}-{self.query('TF')}"

    @property
    def instrument_id(self) -> str:
        return (f"{self.instrument_type} {self._software_version()[1]} SN:{self.query('TT')} "
                f"@ {self.device_port}")

    @property
    def battery_level(self) -> float:
        return parse_double(self.query("MB"))

    # -- the detector ----------------------------------------------------------------------------
    @property
    def detector_id(self) -> str:
        """`GK`, then the head EEPROM: magic `PT9610` (GC0…5), the name (GC16…31) and the serial (GC6, GC7)."""
        name = self.query("GK")
        if not name.strip():
            return ""
        if "".join(chr(parse_int(self.query(f"GC{i}"))) for i in range(6)) != "PT9610":
            return ""
        secret = "".join(chr(parse_int(self.query(f"GC{i}"))) for i in range(0x10, 0x20))
        low = int(self.query("GC6"))
        serial_no = int(self.query("GC7")) * 256 + low
        return f"{name} SN:{serial_no} ({secret.strip()})"

    @property
    def calibration_factor(self) -> float:
        return parse_double(self.query("GS4"))

    @property
    def photometric_unit(self) -> str:
        return self.query("GU")

    # -- measuring -------------------------------------------------------------------------------
    def get_current(self) -> float:
        return parse_double(self.query("MA"))

    def get_photometric_value(self) -> float:
        return parse_double(self.query("MV"))

    def get_measurement_range(self) -> str:
        return RANGE_NAMES.get(self.query("GR"), "Unknown")

    def set_measurement_range(self, range_name: str) -> None:
        self.deselect_auto_range()
        self.query(f"SR{int(range_name.removeprefix('Range')) - 3}")

    def select_auto_range(self) -> None:
        self.query("SB1")

    def deselect_auto_range(self) -> None:
        self.query("SB0")


@pytest.fixture
def world() -> SimWorld:
    """A warm, steady lamp at nominal current, no meter noise."""
    cfg = RigConfig(meter=MeterConfig(calibration_lx_per_a=CAL),
                    simulation=SimulationConfig(warmup_amplitude=0.0, drift_per_hour=0.0, meter_noise_rel=0.0))
    world = SimWorld(cfg, get_model("lambert"), {"kd": 0.5})
    world.lamp.set_current(cfg.lamp.current_a, 0)
    world.lamp.switch(True)
    return world


@pytest.fixture
def peer(world):
    with P9710Peer(world) as p:
        yield p


def in_manual_form(command: str, answer: str) -> bool:
    key = command if command in MANUAL_FORMS else command[:2]
    return re.fullmatch(MANUAL_FORMS[key], answer) is not None


def test_identity_and_detector_as_a_real_unit_gave_them(peer):
    client = PublicClient(f" {peer.path} ")
    assert client.instrument_id == f"P9710-521 V5.6 SN:1875 @ {peer.path}"       # real: "... @ COM5"
    assert client.detector_id == "VL__ SN:52365 (GO2000)"                        # real, dumpDetector1.txt
    assert peer.autorange
    commands = [c for c, _ in client.dialogue]
    assert commands == ["SB1", "GI", "TF", "GI", "TT", "GK", *(f"GC{i}" for i in (*range(6), *range(16, 32))),
                        "GC6", "GC7"]
    assert [(c, a) for c, a in client.dialogue if not in_manual_form(c, a)] == []


def test_calibration_battery_and_readings(peer, world):
    """The manual's `MB` answer `xxx%` is no number to .NET's parser: the client's battery level is NaN against
    our peer (and, by the manual, against a real unit). GS4 is the manual's factor (result = current × factor,
    §16), lx per A; P9710.cs's README calls it A per unit."""
    client = PublicClient(peer.path)
    assert client.calibration_factor == pytest.approx(CAL, rel=1e-4) and client.photometric_unit == "lx"
    assert math.isnan(client.battery_level)
    current = client.get_current()
    assert current == pytest.approx(world.illuminance_normal_lx() / CAL, rel=1e-4)
    assert client.get_photometric_value() == pytest.approx(current * client.calibration_factor, rel=1e-3)
    assert client.get_measurement_range() == "Range05"          # range 2: 20 µA full scale
    assert [(c, a) for c, a in client.dialogue if not in_manual_form(c, a)] == []


def test_a_fixed_range_too_sensitive_reads_nan_and_autorange_recovers(peer, world):
    """`SetMeasurementRange` switches autorange off and sets the range; 5 µA on the 200 pA range is an overload
    (`?16`), which the client's parser turns into NaN; `SB1` brings the reading back."""
    client = PublicClient(peer.path)
    client.set_measurement_range("Range10")
    assert not peer.autorange and client.get_measurement_range() == "Range10"
    assert math.isnan(client.get_current())
    assert client.dialogue[-1] == ("MA", "?16")
    client.select_auto_range()
    assert client.get_current() == pytest.approx(world.illuminance_normal_lx() / CAL, rel=1e-4)
    assert client.get_measurement_range() == "Range05"
    settings = [(c, a) for c, a in client.dialogue if c[:2] in ("SB", "SR")]
    assert settings == [("SB1", ""), ("SB0", ""), ("SR7", ""), ("SB1", "")]
