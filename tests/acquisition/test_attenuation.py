"""Neutral-density attenuation (rig.acquisition.attenuation) with the simulated camera and a wheel that puts
its filter into the simulated world: a glossy peak is taken through the clearest filter that does not clip,
the dim points after it go back to the open position after one probe frame, and the luminance comes out of
the filter with the transmission's uncertainty in its budget."""

import numpy as np
import pytest

from rig.acquisition.attenuation import (
    AttenuatedAcquisition,
    AttenuatingCapturer,
    Attenuation,
    Filter,
    attenuated,
    shorter_way,
)
from rig.acquisition.capture import RawCapturer
from rig.acquisition.capturer import capturer_for
from rig.config.campaign import Capture
from rig.config.rigfile import simulated_rig
from rig.core.errors import DeviceError
from rig.core.values import LuminanceImage, Window
from rig.drivers.interfaces import Attenuator, CalibratedLuminanceCamera
from rig.physics.brdf_models import get_model
from rig.physics.geometry import AXIS_NAMES, inverse_deg
from rig.simulators.camera import SimCamera
from rig.simulators.world import SimWorld

GLOSSY = {"kd": 0.05, "ks": 0.8, "n": 3000.0}         # peak 382 sr⁻¹
FILTERS = [Filter(f.position, f.transmission, f.u_rel) for f in simulated_rig().attenuator.filters]


class WorldWheel(Attenuator):
    """A filter wheel whose position is the simulated world's (the FW102C peer does the same over its pty)."""

    positions = 6

    def __init__(self, world: SimWorld):
        self.world = world
        self.at = 1
        self.moves: list[int] = []
        world.filter_position = lambda: self.at

    def identity(self) -> str:
        return "test wheel"

    def move_to(self, position: int) -> None:
        if position != self.at:
            self.moves.append(position)
            self.world.clock.advance(1.0 * abs(position - self.at))      # the wheel's second per position
        self.at = position

    def position(self) -> int:
        return self.at


def posed(world: SimWorld, theta_i: float, theta_o: float, phi_o: float) -> None:
    for name, value in zip(AXIS_NAMES, inverse_deg(theta_i, 0, theta_o, phi_o).as_array()):
        world.axis_truth[name] = lambda value=float(value): value


@pytest.fixture
def rig():
    world = SimWorld(simulated_rig(), get_model("modified_phong"), GLOSSY)
    world.lamp.set_current(world.config.lamp.current_a, 0)
    world.lamp.switch(True)
    wheel, events = WorldWheel(world), []
    attenuation = Attenuation(wheel, FILTERS, lambda kind, **f: events.append((kind, f)), world.clock)
    return world, wheel, attenuation, capturer_for(SimCamera(world), Capture().settings(), world.clock), events


def through(attenuation: Attenuation, capturer) -> tuple[AttenuatedAcquisition, Filter]:
    """A point acquired by `capturer` behind the wheel (as the run's capturer on a rig with one), and its filter."""
    acquisition = AttenuatingCapturer(capturer, attenuation).acquire()
    return acquisition, acquisition.used


def truth_luminance(world: SimWorld, theta_i: float, theta_o: float, phi_o: float) -> float:
    wi, wo = (np.array([np.sin(np.radians(t)) * np.cos(np.radians(p)), np.sin(np.radians(t)) * np.sin(np.radians(p)),
                        np.cos(np.radians(t))]) for t, p in ((theta_i, 0.0), (theta_o, phi_o)))
    return float(world.brdf(wi[None], wo[None])[0] * world.illuminance_normal_lx() * np.cos(np.radians(theta_i)))


def test_the_peak_is_taken_through_the_clearest_filter_that_does_not_clip(rig):
    world, wheel, attenuation, capturer, events = rig
    posed(world, 20, 20, 180)                                # the mirror direction: 382 sr⁻¹
    acquisition, used = through(attenuation, capturer)
    assert used.position > 1 and wheel.moves == list(range(2, used.position + 1))    # one denser step at a time
    assert not acquisition.clipped and not acquisition.acquisition.roi_merge.clipped.any()
    capture = acquisition.reduce()
    assert "roi_saturated" not in capture.flags and capture.filter_position == used.position
    assert capture.u_rel_attenuation == used.u_rel and capture.transmission == used.transmission
    truth = truth_luminance(world, 20, 20, 180)
    assert abs(capture.luminance_cd_m2 / truth - 1) < 0.1     # the ROI averages the lobe; ≈ the peak
    assert [kind for kind, _ in events] == ["filter"] * (1 + len(wheel.moves))
    assert events[-1][1]["what"] == "ROI saturated at the shortest exposure"


def test_without_a_wheel_the_peak_is_a_lower_bound(rig):
    world, _, _, capturer, _ = rig
    posed(world, 20, 20, 180)
    capture = capturer.acquire().reduce()
    assert "roi_saturated" in capture.flags and capture.filter_position == 0


def test_the_wheel_wraps_the_capturer_once_and_only_on_a_rig_with_one(rig):
    """capturer_for chooses per run: the camera's own capturer without a wheel, behind the wheel with one."""
    world, _, attenuation, _, _ = rig
    settings = Capture().settings()
    assert type(capturer_for(SimCamera(world), settings, world.clock)) is RawCapturer
    wrapped = capturer_for(SimCamera(world), settings, world.clock, attenuation)
    assert isinstance(wrapped, AttenuatingCapturer) and type(wrapped.capturer) is RawCapturer
    assert wrapped.roi == wrapped.capturer.roi and wrapped.sensor == wrapped.capturer.sensor


def test_a_dim_point_after_the_peak_goes_back_to_the_open_position_after_a_probe(rig):
    world, wheel, attenuation, capturer, _ = rig
    posed(world, 20, 20, 180)
    through(attenuation, capturer)
    dense = wheel.at
    posed(world, 20, 30, 180)                                # off the lobe: the diffuse base, 0.016 sr⁻¹
    _, used = through(attenuation, capturer)
    assert used.position == 1 and wheel.moves[-1] == 1 and dense > 1


def test_points_that_never_saturate_never_move_the_wheel(rig):
    world, wheel, attenuation, capturer, _ = rig
    for theta_o in (30, 40, 50):
        posed(world, 20, theta_o, 180)
        _, used = through(attenuation, capturer)
        assert used.position == 1
    assert wheel.moves == []


class OverflowingLmk(CalibratedLuminanceCamera):
    """A camera that calibrates its own pictures, each overflowing everywhere."""

    sensor = simulated_rig().camera.sensor_info()

    def identity(self) -> str:
        return "overflowing LMK"

    def capture_luminance(self, exposure_s: float, window: Window | None = None) -> LuminanceImage:
        raise AssertionError("no single picture: the capture is an HDR one, and the wheel is never probed")

    def capture_hdr_luminance(self, max_exposure_s, min_exposure_s, factor, window=None) -> LuminanceImage:
        return LuminanceImage(np.full((window.height, window.width), 1e6, np.float32), window, (min_exposure_s,),
                              "high_dynamic", overflow_fraction=1.0, peak_load=1.0)


def test_a_camera_with_its_own_attenuation_keeps_the_wheel_on_the_clearest_filter(rig):
    """Its acquisitions never count as clipped (they say so themselves): the overflowing point is flagged,
    not retaken through a denser filter, and the wheel is never probed."""
    world, wheel, attenuation, _, events = rig
    acquisition = capturer_for(OverflowingLmk(), Capture().settings(), world.clock, attenuation).acquire()
    assert acquisition.used.position == 1 and wheel.moves == [] and [e[1]["what"] for e in events] == ["start"]
    assert "roi_saturated" in acquisition.reduce().flags


def test_attenuated_divides_every_luminance_and_adds_the_transmission_uncertainty(rig):
    world, _, _, capturer, _ = rig
    posed(world, 20, 30, 180)
    capture = capturer.acquire().reduce()
    nd = Filter(3, 0.01, 0.02)
    out = attenuated(capture, nd)
    for name in ("luminance_cd_m2", "roi_std_cd_m2", "u_noise_cd_m2", "u_dark_cd_m2", "u_texture_cd_m2"):
        assert getattr(out, name) == pytest.approx(getattr(capture, name) / 0.01, rel=1e-12)
    assert out.u_luminance_cd_m2 == pytest.approx(np.hypot(capture.u_luminance_cd_m2 / 0.01,
                                                           0.02 * out.luminance_cd_m2), rel=1e-12)
    assert (out.filter_position, out.transmission, out.u_rel_attenuation) == (3, 0.01, 0.02)


def test_filters_beyond_the_wheel_are_refused():
    world = SimWorld(simulated_rig(), get_model("lambert"), {"kd": 0.5})
    with pytest.raises(DeviceError, match=r"test wheel has 6 positions; the rig file's filters name position"):
        Attenuation(WorldWheel(world), [*FILTERS[:2], Filter(7, 1e-6, 0.05)], lambda kind, **f: None, world.clock)


@pytest.mark.parametrize("start, target, size, path", [
    (1, 4, 6, [2, 3, 4]), (1, 5, 6, [6, 5]), (6, 1, 6, [1]), (3, 3, 6, []), (2, 11, 12, [1, 12, 11]),
    (1, 7, 12, [2, 3, 4, 5, 6, 7]),
])
def test_the_wheel_turns_one_position_at_a_time_the_shorter_way(start, target, size, path):
    assert shorter_way(start, target, size) == path


def test_keep_alives_run_between_the_single_position_moves():
    """A far move is a series of one-position moves, each blocking about a second: the lamp's watchdog is fed
    between them, never starved for the whole way."""
    world = SimWorld(simulated_rig(), get_model("lambert"), {"kd": 0.5})
    wheel, fed = WorldWheel(world), []
    world.clock.keep_alive(0.5, lambda: fed.append(wheel.at))
    far = [FILTERS[0], Filter(4, 1e-3, 0.015)]
    attenuation = Attenuation(wheel, far, lambda kind, **f: None, world.clock)
    attenuation._move(1, reason="test")
    assert wheel.moves == [2, 3, 4] and fed == [2, 3, 4]
