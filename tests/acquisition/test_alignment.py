"""Aligning the arm on a glossy sample's specular peak (rig.acquisition.alignment), on the simulated rig over
its real protocols (AZ drives over Modbus TCP, the FW102C wheel over a pty), with zero errors five times the
default so that the effect is plain: after the alignment the camera looks along the sample's physical mirror
direction, at every incidence, to a small fraction of the zero errors."""

import numpy as np
import pytest

from rig.acquisition.alignment import AlignmentError, align_on_specular, align_run, scan_grid_deg
from rig.acquisition.attenuation import attenuation_for
from rig.acquisition.capturer import capturer_for
from rig.acquisition.moves import Mover
from rig.config.campaign import Capture, SpecularAlignment
from rig.config.rigfile import SimulationConfig, simulated_rig
from rig.physics import geometry as geo
from rig.simulators.rig import SimulatedRig

GLOSSY = {"kd": 0.05, "ks": 0.8, "n": 3000.0}


class Session:
    """A lit simulated rig with a mover and a capture through the wheel, as the engine has them."""

    def __init__(self, sim: SimulatedRig, rig):
        dev = sim.devices
        dev.lamp.set_output(True)
        dev.lamp.set_current(rig.lamp.current_a)
        self.world = sim.world
        self.mover = Mover(dev, rig)
        self.events: list[tuple[str, dict]] = []
        capturer = capturer_for(dev.camera, Capture().settings(), dev.clock,
                                attenuation_for(dev, rig.attenuator, lambda kind, **f: None))
        self.capture = lambda: capturer.acquire().reduce()

    def event(self, kind, **fields):
        self.events.append((kind, fields))

    def view_error_deg(self, theta_i_deg: float) -> float:
        """Move (as aligned so far) to the nominal mirror geometry; how far the recorded view direction
        relative to the mirror direction is from the physical one (the simulated world's true axis angles):
        the error a point on a lobe centred on the mirror direction gets. A move's own positioning error is
        seen by the encoders and recorded, so it is not part of it."""
        target = geo.inverse_deg(theta_i_deg, 0, theta_i_deg, 180, self.mover.rig.axes.limits(),
                                 self.mover.position).as_array()
        self.mover.move(tuple(float(v) for v in target))
        off = []
        for motors in ([self.world.axis_truth[n]() for n in geo.AXIS_NAMES], self.mover.read_back()):
            wi, wo = geo.directions_scs(*np.radians(motors))
            off.append(wo - geo.mirror_direction(wi))
        return float(np.degrees(np.linalg.norm(off[0] - off[1])))


@pytest.fixture
def session():
    rig = simulated_rig().model_copy(update={"simulation": SimulationConfig(seed=5, axis_zero_sigma_deg=0.05)})
    with SimulatedRig(rig, "modified_phong", GLOSSY) as sim:
        yield Session(sim, rig)


def test_the_scan_is_a_serpentine_of_single_steps_between_two_visits_of_its_centre():
    spec = SpecularAlignment(step_deg=0.25, steps=5)
    az, polar = scan_grid_deg(spec)
    assert (az[0], polar[0]) == (az[-1], polar[-1]) == (0.0, 0.0)            # early and late: the lamp's drift
    grid = list(zip(az[1:-1].round(9), polar[1:-1].round(9)))
    assert sorted(grid) == sorted((round(a, 9), round(p, 9)) for a in 0.25 * np.arange(-2, 3)
                                  for p in 0.25 * np.arange(-2, 3))
    assert np.allclose(np.hypot(np.diff(az[1:-1]), np.diff(polar[1:-1])), 0.25)


def test_alignment_points_the_arm_along_the_physical_mirror_direction_at_every_incidence(session):
    before = [session.view_error_deg(t) for t in (20, 45, 70)]
    found = align_run(SpecularAlignment(theta_i_deg=45), {}, session.mover, session.capture, session.event,
                      lambda **changes: session.events.append(("manifest", changes)))
    after = [session.view_error_deg(t) for t in (20, 45, 70)]
    assert min(before) > 0.03, before                          # zero errors of σ 0.05° per axis
    assert max(after) < 0.006, (before, after)
    assert 0 < found.u_deg < 0.005
    assert found.lobe_width_deg == pytest.approx(np.degrees(1 / np.sqrt(3000)), rel=0.15)
    kinds = [k for k, _ in session.events]
    assert kinds[-2:] == ["manifest", "aligned"] and set(kinds[:-2]) == {"alignment_scan"} and len(kinds) <= 4
    scan = session.events[0][1]
    assert len(scan["luminance_cd_m2"]) == 27 and max(scan["luminance_cd_m2"]) > 1e5     # through ND filters


def test_a_resumed_run_keeps_the_alignment_it_was_measured_with(session):
    saved = {"arm_azimuth_zero_deg": 0.02, "arm_polar_zero_deg": -0.01, "u_deg": 0.001, "theta_i_deg": 45.0,
             "lobe_width_deg": 1.0}

    def no_capture():
        raise AssertionError("a resumed run does not scan again")
    found = align_run(SpecularAlignment(), {"alignment": saved}, session.mover, no_capture, session.event,
                      lambda **changes: None)
    assert session.mover.arm_zero_deg == (0.02, -0.01) and found.as_dict() == saved
    assert session.events == [("aligned", {"reused": True, **saved})]


def test_a_peak_further_than_allowed_stops_the_alignment_naming_it(session):
    with pytest.raises(AlignmentError, match=r"θi=45°: the peak lies 0\.\d+° from .*alignment.max_offset_deg 0\.001°"):
        align_on_specular(SpecularAlignment(max_offset_deg=0.001), session.mover, session.capture, session.event)


def test_a_diffuse_sample_has_no_peak_to_align_on():
    rig = simulated_rig()
    with SimulatedRig(rig, "lambert", {"kd": 0.5}) as sim:
        s = Session(sim, rig)
        with pytest.raises(AlignmentError, match="no maximum.*is the sample glossy"):
            align_on_specular(SpecularAlignment(), s.mover, s.capture, s.event)
