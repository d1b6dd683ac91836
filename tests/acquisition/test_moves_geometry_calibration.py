"""Moves and read-backs with a geometry calibration (rig.acquisition.moves.Mover, docs/geometry-calibration.md): on
the simulated rig with zero errors of σ 0.3°, a rig that knows them puts every axis at the physical angle asked
for and records the physical angle; one that does not is off by the zero errors."""

import numpy as np
import pytest

from rig.acquisition.moves import Mover
from rig.config.geometry_calibration import GeometryCalibrationSummary
from rig.config.rigfile import SimulationConfig, simulated_rig
from rig.physics.geometry import AXIS_NAMES
from rig.simulators.rig import SimulatedRig

TARGET = (-30.0, -45.0, -60.0, 50.0)
#: A move's repeatability and half the backlash, which the encoders see and the read-back carries.
POSITIONING_DEG = 0.01


def _rig(calibrated: bool):
    rig = simulated_rig().model_copy(update={"simulation": SimulationConfig(seed=3, axis_zero_sigma_deg=0.3)})
    world = SimulatedRig(rig, "lambert", {"kd": 0.5}).world          # the truths, drawn as the run will
    zeros = tuple(world.axis_zero_deg[name] for name in AXIS_NAMES)
    if calibrated:
        summary = GeometryCalibrationSummary(file="geometry.yaml", date="2026-11-27T00:00:00+00:00",
                                             zero_offsets_deg=zeros, zero_u_deg=(0.002,) * 4)
        rig = rig.model_copy(update={"geometry": rig.geometry.model_copy(update={"calibration": summary})})
    return rig, np.array(zeros)


@pytest.mark.parametrize("calibrated", [True, False])
def test_moves_reach_and_record_the_physical_angles_when_the_rig_knows_its_zero_offsets(calibrated):
    rig, zeros = _rig(calibrated)
    with SimulatedRig(rig, "lambert", {"kd": 0.5}) as sim:
        mover = Mover(sim.devices, rig)
        mover.move(TARGET)
        physical = np.array([sim.world.axis_truth[name]() for name in AXIS_NAMES])
        recorded = np.array(mover.read_back())
    assert np.max(np.abs(zeros)) > 0.2
    if calibrated:
        assert physical == pytest.approx(TARGET, abs=POSITIONING_DEG)
        assert recorded == pytest.approx(physical, abs=0.002)
    else:
        assert physical - np.array(TARGET) == pytest.approx(zeros, abs=POSITIONING_DEG)
        assert recorded == pytest.approx(physical - zeros, abs=0.002)
