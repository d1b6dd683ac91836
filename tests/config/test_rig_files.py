"""Rig files: the shipped ones load, the simulated one is the default, bad ones are refused clearly."""


import pytest
import yaml

from repo_paths import E2E_CAMPAIGN, RIGS
from rig.cli.main import main
from rig.config.rigdevices import LampDevice
from rig.config.rigfile import RigConfig, RigConfigError, load_rig_config, simulated_rig
from rig.core.errors import DeviceError
from rig.devices import connect_devices, vendor_camera
from rig.simulators.clock import SimClock


def test_simulated_rig_file_is_the_default():
    assert load_rig_config(RIGS / "simulated.yaml") == simulated_rig()


def test_example_lab_rig_file_loads():
    cfg = load_rig_config(RIGS / "example-lab.yaml")
    assert not cfg.simulated
    assert cfg.devices.arm.address.startswith("modbus-tcp://")
    assert cfg.devices.stage.address.startswith("modbus-rtu://")
    assert cfg.devices.lamp.address.endswith(":8462")
    assert cfg.devices.camera.driver == "lmk"


@pytest.mark.parametrize("change, key, rule", [
    ({"devices": {"lamp": {"driver": "Keithley 2200"}}}, "devices.lamp", "a registered driver name"),
    ({"devices": {"camera": {"driver": "LMK"}}}, "devices.camera", "a registered driver name"),
    ({"devices": {"lamp": {"options": {"port": 1}}}}, "devices.lamp", "driver delta-sm takes no options"),
    ({"axes": {"arm_polar": {"limits_deg": [90, -90], "speed_deg_s": 1, "accel_deg_s2": 1}}},
     "axes.arm_polar", "low < high"),
    ({"geometry": {"camera_distance_m": -1}}, "geometry.camera_distance_m", "greater than 0"),
    ({"meter": {"calibration": 3}}, "meter.calibration", "allowed here: calibration_lx_per_a"),
    ({"lamp": {"current_a": 5.0, "current_limit_a": 4.6}}, "lamp", "exceeds current_limit_a"),
    ({"lamp": {"watchdog_s": 30}}, "lamp.watchdog_s", "less than or equal to 10"),
    ({"lamp": {"watchdog_s": 0.01}}, "lamp.watchdog_s", "greater than or equal to 0.02"),
    ({"meter": {"integration_s": 6}}, "meter.integration_s", "less than or equal to 5.9999"),
    ({"meter": {"integration_s": 2, "autorange_s": 1}, "lamp": {"watchdog_s": 5}}, "(top level)",
     "blocks the lamp's keep-alive"),
    ({"devices": {"camera": {"driver": "python:rig.drivers.lmk:LmkCamera"}}}, "(top level)",
     "camera.max_exposure_s (15 s) must be at most half of lamp.watchdog_s"),
    ({"devices": {"camera": {"driver": "rig-sim-camera", "options": {"address": "/dev/ttyS0"}}}}, "devices.camera",
     "takes exactly options: {address: socket://host:port}"),
    ({"time_scale": 0}, "time_scale", "greater than 0"),
    ({"meter": {"range_u_rel": [0.01, 0.01]}}, "meter.range_u_rel[2]", "missing key"),
])
def test_bad_rig_file(tmp_path, change, key, rule):
    f = tmp_path / "rig.yaml"
    f.write_text(yaml.safe_dump(change))
    with pytest.raises(RigConfigError) as err:
        load_rig_config(f)
    line = next(text for text in str(err.value).splitlines() if f"'{key}'" in text)
    assert rule in line


def test_a_driver_that_is_not_installed_is_refused_naming_those_that_are():
    from rig.devices import check_devices

    lab = load_rig_config(RIGS / "example-lab.yaml")
    devices = lab.devices.model_copy(update={"lamp": LampDevice(driver="keithley", address="socket://h:1")})
    with pytest.raises(RigConfigError, match=r"devices.lamp.driver'.*no lamp driver named 'keithley' is installed; "
                                             r"installed: delta-sm"):
        check_devices(lab.model_copy(update={"devices": devices}))


def test_a_camera_that_calibrates_itself_refuses_a_calibration_file():
    from rig.devices import check_devices

    lab = load_rig_config(RIGS / "example-lab.yaml")            # the LMK: calibrated luminance from LabSoft
    check_devices(lab)
    camera = lab.camera.model_copy(update={"calibration_file": "cam.yaml"})
    with pytest.raises(RigConfigError, match=r"camera.calibration_file'.*'lmk' delivers calibrated luminance"):
        check_devices(lab.model_copy(update={"camera": camera}))


def test_a_plug_in_entry_is_its_name_and_its_options(tmp_path):
    f = tmp_path / "rig.yaml"
    f.write_text(yaml.safe_dump({"devices": {"lamp": {"driver": "keithley-2200", "address": "tcp://x", "channel": 2},
                                             "camera": {"driver": "lmk", "camera": "dxm", "lens": "o25"}},
                                 "camera": {"max_exposure_s": 2}}))
    rig = load_rig_config(f)
    assert rig.devices.lamp.options == {"address": "tcp://x", "channel": 2}
    assert rig.devices.lamp.driver_options() == {"address": "tcp://x", "channel": 2}
    assert rig.devices.camera.options == {"camera": "dxm", "lens": "o25"}
    assert RigConfig().devices.lamp.driver_options() == {"address": "auto", "timeout_s": 1.0}


def test_auto_address_needs_the_simulated_rig():
    with pytest.raises(RigConfigError, match="'devices.arm.address': address 'auto' only works on the simulated rig"):
        connect_devices(RigConfig(simulated=False), SimClock())


def test_unreachable_device_is_named(tmp_path):
    cfg = load_rig_config(RIGS / "example-lab.yaml")
    local = cfg.devices.model_copy(update={"arm": cfg.devices.arm.model_copy(
        update={"address": "modbus-tcp://127.0.0.1:9", "timeout_s": 0.2})})
    with pytest.raises(DeviceError, match="arm"):
        connect_devices(cfg.model_copy(update={"devices": local}), SimClock())


def uninstalled_camera_rig() -> RigConfig:
    """The example lab's rig with a camera plug-in from a package this machine does not have."""
    cfg = load_rig_config(RIGS / "example-lab.yaml")
    camera = cfg.devices.camera.model_copy(update={"driver": "python:mylab.lmk:LmkCamera", "options": {}})
    return cfg.model_copy(update={"devices": cfg.devices.model_copy(update={"camera": camera})})


def test_vendor_camera_import_error_is_clear():
    cfg = uninstalled_camera_rig()
    with pytest.raises(DeviceError, match="cannot load camera driver 'python:mylab.lmk:LmkCamera'"):
        vendor_camera(cfg, cfg.devices.camera)


def test_rig_devices_prints_identities_and_moves_nothing(capsys):
    assert main(["devices", str(RIGS / "simulated.yaml")]) == 0
    out = capsys.readouterr().out
    for role in ("arm", "stage", "lamp", "meter", "camera"):
        assert f"\n{role}" in "\n" + out
    assert "DELTA ELEKTRONIKA" in out and "P9710" in out and "Modbus" in out
    assert "THORLABS FW102C" in out.upper() and "attenuator: position 1 of 6" in out
    assert "output off" in out


def test_rig_devices_bad_file(tmp_path, capsys):
    f = tmp_path / "r.yaml"
    f.write_text("devices: [1, 2]\n")
    assert main(["devices", str(f)]) == 2
    assert "invalid rig configuration" in capsys.readouterr().err


def test_run_with_rig_option(tmp_path):
    campaign = E2E_CAMPAIGN
    assert main(["plan", str(campaign), "--rig", str(RIGS / "simulated.yaml")]) == 0


# -- strict rig files (issue 9) ------------------------------------------------------------------
@pytest.mark.parametrize("device, address", [
    ("arm", "modbus-tcp://192.168.10.21"),            # no port
    ("arm", "modbus-tcp://192.168.10.21:0"),
    ("arm", "modbus-tcp://192.168.10.21:70000"),
    ("arm", "modbus-tcp://:502"),
    ("stage", "modbus-rtu:///dev/ttyUSB0?baud=9600"),  # unknown option
    ("stage", "modbus-rtu:///dev/ttyUSB0?baudrate=fast"),
    ("stage", "modbus-rtu://ttyUSB0"),
    ("stage", "tcp://192.168.10.21:502"),
    ("lamp", "socket://192.168.10.30"),
    ("lamp", "telnet://192.168.10.30:23"),
    ("meter", "ttyUSB1"),
    ("meter", "/dev/tty USB1"),
])
def test_bad_addresses_are_refused(tmp_path, device, address):
    f = tmp_path / "rig.yaml"
    f.write_text(yaml.safe_dump({"simulated": False, "devices": {device: {"address": address}}}))
    with pytest.raises(RigConfigError, match=f"'devices.{device}.address'"):
        load_rig_config(f)


@pytest.mark.parametrize("address", ["modbus-tcp://192.168.10.21:502", "modbus-tcp://[fe80::1]:1502",
                                     "modbus-rtu:///dev/ttyUSB0?baudrate=19200&parity=E&stopbits=1",
                                     "modbus-rtu://COM3", "modbus-rtu://socket://10.0.0.5:4001"])
def test_good_positioner_addresses_load(tmp_path, address):
    """What the rig file accepts, the driver can open (it does not connect until asked)."""
    from rig.drivers.modbus_drive import modbus_client

    f = tmp_path / "rig.yaml"
    f.write_text(yaml.safe_dump({"devices": {"arm": {"address": address}}}))
    assert load_rig_config(f).devices.arm.address == address
    modbus_client(address, 0.1).close()


@pytest.mark.parametrize("text, key", [
    ("axes: {arm_polar: {limits_deg: [-180, 180], speed_deg_s: .inf, accel_deg_s2: 30}}", "axes.arm_polar.speed_deg_s"),
    ("axes: {arm_polar: {limits_deg: [-.inf, .inf], speed_deg_s: 15, accel_deg_s2: 30}}",
     "axes.arm_polar.limits_deg[0]"),
    ("axes: {arm_polar: {limits_deg: [-180, 1e6], speed_deg_s: 15, accel_deg_s2: 30}}", "axes.arm_polar.limits_deg[1]"),
    ("meter: {repeatability_rel: .nan}", "meter.repeatability_rel"),
    ("camera: {min_exposure_s: 20, max_exposure_s: 15}", "camera"),
    ("camera: {black_level_dn: 5000}", "camera"),
    ("simulation: {seed: -1}", "simulation.seed"),
    ("devices: {arm: {steps_per_degree: 1.0e6}}\naxes: {arm_azimuth: {limits_deg: [-180, 180], speed_deg_s: 15, "
     "accel_deg_s2: 3000}}", "(top level)"),
    ("devices: {arm: {timeout_s: 1e308}}", "devices.arm.timeout_s"),
])
def test_non_finite_and_insane_rig_values_are_refused(tmp_path, text, key):
    f = tmp_path / "rig.yaml"
    f.write_text(text + "\n")
    with pytest.raises(RigConfigError) as err:
        load_rig_config(f)
    assert f"'{key}'" in str(err.value)


PLUGIN = '''
from rig.core.values import Frame
from rig.drivers.interfaces import LuminanceCamera


class Good(LuminanceCamera):
    def __init__(self, config, **options):
        self.sensor = config.sensor_info()
        self.options = options

    def identity(self):
        return "good camera"

    def capture(self, exposure_s, window=None):
        raise NotImplementedError

    def capture_dark(self, exposure_s, window=None):
        raise NotImplementedError


class NoOptions(Good):
    def __init__(self, config):
        super().__init__(config)


class Explodes(Good):
    def __init__(self, config, **options):
        raise RuntimeError("SDK licence not found")


class Abstract(LuminanceCamera):
    def __init__(self, config, **options):
        pass


class NotACamera:
    def __init__(self, config, **options):
        pass


not_a_class = 3
'''


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    (tmp_path / "rigfuzzplugin.py").write_text(PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))

    def config(cls: str, options: dict | None = None) -> RigConfig:
        lab = load_rig_config(RIGS / "example-lab.yaml")
        camera = lab.devices.camera.model_copy(update={"driver": f"python:rigfuzzplugin:{cls}",
                                                       "options": options or {"server": "x"}})
        return lab.model_copy(update={"devices": lab.devices.model_copy(update={"camera": camera})})
    return config


@pytest.mark.parametrize("cls, rule", [
    ("NoOptions", "constructor does not take"), ("Abstract", "does not implement capture"),
    ("NotACamera", "not a class implementing"), ("not_a_class", "not a class implementing"),
    ("Missing", "cannot load camera driver"),
])
def test_camera_plugin_is_checked_before_connecting(plugin, cls, rule):
    from rig.devices import check_devices

    with pytest.raises(RigConfigError, match=f"'devices.camera.driver'.*{rule}"):
        check_devices(plugin(cls))


def test_good_camera_plugin_passes_and_builds(plugin):
    from rig.devices import check_devices

    cfg = plugin("Good")
    check_devices(cfg)
    camera = vendor_camera(cfg, cfg.devices.camera)
    assert camera.identity() == "good camera" and camera.options == {"server": "x"}


def test_camera_plugin_failing_to_start_is_a_device_error(plugin):
    cfg = plugin("Explodes")
    with pytest.raises(DeviceError, match="failed to start: RuntimeError: SDK licence not found"):
        vendor_camera(cfg, cfg.devices.camera)


def test_uninstalled_camera_plugin_is_bad_input_before_connecting():
    from rig.devices import check_devices

    with pytest.raises(RigConfigError, match="cannot load camera driver 'python:mylab.lmk:LmkCamera'"):
        check_devices(uninstalled_camera_rig())
    check_devices(load_rig_config(RIGS / "example-lab.yaml"))   # the LMK driver ships with rig
    check_devices(RigConfig())      # the simulated rig brings its own camera


@pytest.mark.parametrize("devices, key", [({}, "devices.arm.address"),
                                          ({"arm": {"address": "modbus-tcp://10.0.0.1:502"},
                                            "stage": {"address": "modbus-tcp://10.0.0.2:502"},
                                            "lamp": {"address": "/dev/ttyUSB1"}, "meter": {"address": "COM4"}},
                                           "devices.camera.driver")])
def test_hardware_rig_without_addresses_or_camera_is_bad_input(devices, key):
    from rig.devices import check_devices

    cfg = RigConfig.model_validate({"simulated": False, "devices": devices})
    with pytest.raises(RigConfigError, match=f"'{key}'.*only .* the simulated rig"):
        check_devices(cfg)


def test_a_drive_map_of_ones_own_is_read_relative_to_the_rig_file(tmp_path):
    from importlib import resources

    az = resources.files("rig.drivers").joinpath("drive_maps", "oriental-az.yaml").read_text("utf-8")
    (tmp_path / "maps").mkdir()
    (tmp_path / "maps" / "my-drive.yaml").write_text(az.replace("Oriental Motor AZ series", "My drive"))
    rig = tmp_path / "rig.yaml"
    rig.write_text("name: lab\ndevices:\n  arm: {map: maps/my-drive.yaml, device_ids: [5, 6]}\n")
    cfg = load_rig_config(rig)
    assert cfg.devices.arm.map == str(tmp_path / "maps" / "my-drive.yaml") and cfg.devices.stage.map == "oriental-az"
    (tmp_path / "maps" / "my-drive.yaml").write_text(az.replace("0x0058", "-1"))
    with pytest.raises(RigConfigError, match=r"rig.yaml: key 'devices.arm.map': .*my-drive.yaml: key 'move.address'"):
        load_rig_config(rig)


@pytest.mark.parametrize("entry, message", [
    ("{map: fancy-drive}", "no such packaged map (known: oriental-az"),
    ("{device_ids: [1, 1]}", "the two drives need two ids"),
    ("{device_ids: [0, 2]}", "greater than or equal to 1"),
    ("{steps_per_degree: [1000]}", "steps_per_degree"),
])
def test_bad_modbus_drive_entries_are_refused(tmp_path, entry, message):
    rig = tmp_path / "rig.yaml"
    rig.write_text(f"name: lab\ndevices:\n  stage: {entry}\n")
    with pytest.raises(RigConfigError) as err:
        load_rig_config(rig)
    assert "devices.stage" in str(err.value) and message in str(err.value)
