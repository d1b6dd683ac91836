"""A campaign measured on the simulated rig beside its closed-form truth, for the studies that score a method.

The simulated sample's BRDF is known in closed form (the campaign's `sample.simulated_brdf`), so every row can be
compared with the truth at the angles the rig achieved (not the planned ones: the axes miss them by their
read-back error). Used by the benchmarks of capture, glossy samples and geometry calibration.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rig.acquisition.execute import RigOpener
from rig.acquisition.run import run_campaign
from rig.config.campaign import Campaign, SimulatedBrdf
from rig.config.rigfile import RigConfig
from rig.data.dataset_reader import Dataset, load
from rig.drivers.interfaces import RigDevices
from rig.physics.brdf_models import get_model
from rig.physics.geometry import AXIS_NAMES, directions_scs
from rig.session.connect import open_campaign_rig
from rig.simulators.rig import SimulatedRig
from rig.simulators.world import SimWorld


def measured_with_truth(campaign: Campaign, rig: RigConfig, out: Path) -> tuple[Dataset, np.ndarray]:
    """Measure `campaign` on the simulated `rig` into `out` (it must complete); the dataset and the truth per row."""
    spec = _truth(campaign)
    d = _measured(campaign, rig, out, open_campaign_rig)
    wi, wo = d.directions()
    return d, get_model(spec.model)(wi, wo, spec.params)


@dataclass(frozen=True)
class ExactTruth:
    """What the simulated rig really did at each row, from its world (the simulator's truth): the BRDF at the
    axes' physical positions (the read-back plus each axis's zero error, the arm's aligned zero put back), times
    cos θi there over cos θi of the row (the row divides the luminance by E⊥ cos θi at its own angle, the lamp lit
    the sample at the physical one: 0.2 % at θi 85° for a 0.01° zero error), and the true transmission of the row's
    filter over its certificate's (1 without one). Against these a row's error is
    what the rig's shared errors of geometry and filters leave: its own, and what the texture shares."""

    brdf_per_sr: np.ndarray
    transmission_ratio: np.ndarray


def measured_exactly(campaign: Campaign, rig: RigConfig, out: Path) -> tuple[Dataset, ExactTruth]:
    """Measure `campaign` on the simulated `rig` into `out`, and the rows' exact truth (`ExactTruth`). The holder's
    tilt and the camera's mount are not modelled here: a rig that draws them is refused."""
    if rig.simulation.holder_tilt_sigma_deg or rig.simulation.camera_mount_sigma_deg:
        raise ValueError("measured_exactly: the holder's tilt and the camera's mount are not modelled; set their "
                         "simulation sigmas to 0")
    spec = _truth(campaign)
    worlds: list[SimWorld] = []

    @contextmanager
    def opener(_: Campaign, config: RigConfig) -> Iterator[RigDevices]:
        with SimulatedRig(config, spec.model, spec.params) as sim:
            worlds.append(sim.world)
            assert sim.devices is not None
            yield sim.devices
    d = _measured(campaign, rig, out, opener)
    world = worlds[-1]
    alignment = d.manifest.get("alignment") or {}
    offsets = rig.geometry.calibration.zero_offsets_deg if rig.geometry.calibration is not None else (0.0,) * 4
    arm_zero = (alignment.get("arm_azimuth_zero_deg", 0.0), alignment.get("arm_polar_zero_deg", 0.0))
    shift = np.array([world.axis_zero_deg.get(name, 0.0) - off for name, off in zip(AXIS_NAMES, offsets)])
    physical = np.column_stack([d[f"{name}_deg"] for name in AXIS_NAMES]) + shift + np.array([0.0, 0.0, *arm_zero])
    wi, wo = directions_scs(*np.radians(physical.T))
    certified = {flt.position: flt.transmission for flt in rig.attenuator.filters} if rig.attenuator else {}
    ratio = np.array([world.transmission_truth.get(int(p), 1.0) / certified.get(int(p), 1.0)
                      for p in d["filter_position"]])
    # The row divides by E⊥ cos θi at its own θi, the lamp lit the sample at the physical one
    lit = wi[:, 2] / np.cos(np.radians(d["theta_i_deg"]))
    return d, ExactTruth(get_model(spec.model)(wi, wo, spec.params) * lit, ratio)


def _measured(campaign: Campaign, rig: RigConfig, out: Path, opener: RigOpener) -> Dataset:
    outcome = run_campaign(campaign, rig, out, opener)
    if outcome.status != "complete":
        raise RuntimeError(f"campaign {campaign.name!r} ended {outcome.status}: {outcome.error}")
    return load(out)


def _truth(campaign: Campaign) -> SimulatedBrdf:
    """The campaign's simulated sample (its closed-form model and parameters)."""
    if campaign.sample.simulated_brdf is None:
        raise ValueError(f"campaign {campaign.name!r} has no sample.simulated_brdf: nothing to compare with")
    return campaign.sample.simulated_brdf
