"""The example driver plug-in (examples/rig-plugin-example) installed from its own folder: rig lists it,
accepts it in a rig file, refuses options it does not take, and drives it like its own drivers.

pip installs the folder into a temporary directory (build isolation fetches setuptools from the package
registry); the test puts that directory on sys.path, where importlib.metadata finds its entry point.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

from repo_paths import RIGS, ROOT
from rig.config.rigdevices import MeterDevice
from rig.config.rigfile import MeterConfig, RigConfigError, load_rig_config
from rig.devices import check_devices
from rig.drivers.registry import driver_class
from rig.simulators.clock import SimClock
from rig.simulators.line_peer import LinePeer
from rig_process import HANG_S, start_rig

EXAMPLE = ROOT / "examples" / "rig-plugin-example"


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> str:
    target = tmp_path_factory.mktemp("site")
    pip = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--target", str(target),
                          str(EXAMPLE)], capture_output=True, text=True, timeout=HANG_S)
    assert pip.returncode == 0, pip.stderr
    return str(target)


class Picoammeter(LinePeer):
    """Enough of a Keithley 6485 for the driver: identity, settings, one reading (4.82 µA)."""

    def __init__(self):
        super().__init__("tcp")

    def respond(self, line: bytes) -> bytes | None:
        text = line.decode().strip()
        if text == "*IDN?":
            return b"KEITHLEY INSTRUMENTS INC.,MODEL 6485,1234567,C01   Jun 30 2014 09:12:51/A02  /E\n"
        if text == "READ?":
            return b"-4.820000E-06A,+1.234567E+03,+0.000000E+00\n"
        return None


def test_rig_devices_list_shows_the_installed_plug_in_and_its_package(installed):
    proc = start_rig("devices", "--list", env={"PYTHONPATH": installed})
    out, err = proc.communicate(timeout=HANG_S)
    assert proc.returncode == 0, err
    line = next(line for line in out.splitlines() if line.startswith("keithley-6485"))
    assert "meter" in line and "rig-plugin-example 0.1.0" in line
    assert any(line.startswith("delta-sm") for line in out.splitlines())      # rig's own beside it


def test_a_rig_file_names_it_with_its_options_and_rig_drives_it(installed, monkeypatch):
    monkeypatch.syspath_prepend(installed)
    lab = load_rig_config(RIGS / "example-lab.yaml")

    def with_meter(**entry) -> object:
        return lab.model_copy(update={"devices": lab.devices.model_copy(update={"meter": MeterDevice(**entry)})})
    check_devices(with_meter(driver="keithley-6485", address="/dev/ttyUSB1", timeout_s=2))
    with pytest.raises(RigConfigError, match=r"devices.meter.driver'.*keithley-6485' does not take the options "
                                             r"address, port"):
        check_devices(with_meter(driver="keithley-6485", address="/dev/ttyUSB1", port=3))
    with Picoammeter() as peer:
        meter = driver_class("meter", "keithley-6485").from_rig(
            clock=SimClock(pace=0), settings=MeterConfig(calibration_lx_per_a=1e9), address=peer.url)
        try:
            assert "MODEL 6485" in meter.identity()
            reading = meter.read()
            assert reading.photocurrent_a == pytest.approx(4.82e-6)
            assert reading.illuminance_lx == pytest.approx(4820.0)
        finally:
            meter.close()
