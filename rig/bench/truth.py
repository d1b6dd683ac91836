"""A campaign measured on the simulated rig beside its closed-form truth, for the studies that score a method.

The simulated sample's BRDF is known in closed form (the campaign's `sample.simulated_brdf`), so every row can be
compared with the truth at the angles the rig achieved (not the planned ones: the axes miss them by their
read-back error). Used by the benchmarks of capture, glossy samples and geometry calibration.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rig.acquisition.run import run_campaign
from rig.config.campaign import Campaign
from rig.config.rigfile import RigConfig
from rig.data.dataset_reader import Dataset, load
from rig.physics.brdf_models import get_model
from rig.session.connect import open_campaign_rig


def measured_with_truth(campaign: Campaign, rig: RigConfig, out: Path) -> tuple[Dataset, np.ndarray]:
    """Measure `campaign` on the simulated `rig` into `out` (it must complete); the dataset and the truth per row."""
    truth_spec = campaign.sample.simulated_brdf
    if truth_spec is None:
        raise ValueError(f"campaign {campaign.name!r} has no sample.simulated_brdf: nothing to compare with")
    outcome = run_campaign(campaign, rig, out, open_campaign_rig)
    if outcome.status != "complete":
        raise RuntimeError(f"campaign {campaign.name!r} ended {outcome.status}: {outcome.error}")
    d = load(out)
    wi, wo = d.directions()
    return d, get_model(truth_spec.model)(wi, wo, truth_spec.params)
