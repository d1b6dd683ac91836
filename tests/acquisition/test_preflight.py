"""One pre-flight for a new run and a resume (rig.acquisition.preflight, issue 32): what it refuses, before any
device is opened or anything written."""

from collections import namedtuple

import pytest

from rig.acquisition import diskspace
from rig.acquisition.execute import manifest_for
from rig.acquisition.resume import ResumeError
from rig.acquisition.run import resume_campaign, run_campaign
from rig.config.campaign import CampaignError, load_campaign, parse_campaign
from rig.config.rigfile import RigConfig
from rig.core.errors import DeviceError
from rig.data.dataset_format import DatasetError
from rig.data.dataset_writer import DatasetWriter

Usage = namedtuple("Usage", "total used free")
CAMPAIGN_YAML = """name: small
sample: {id: S, simulated_brdf: {model: lambert, params: {kd: 0.5}}}
incidence: [{phi: 0, theta: [0]}]
viewing: [{centred_on: normal, theta: [10, 30], phi: [0, 180]}]
lamp: {warmup_min_s: 60}
"""


def small(**extra):
    return parse_campaign({
        "name": "small", "sample": {"id": "S", "simulated_brdf": {"model": "lambert", "params": {"kd": 0.5}}},
        "incidence": [{"phi": 0, "theta": [0]}], "viewing": [{"centred_on": "normal", "theta": [10], "phi": [0, 180]}],
        "lamp": {"warmup_min_s": 60}, **extra})


def never_opened(campaign, rig):
    raise AssertionError("the pre-flight should have refused before connecting")


def test_an_occupied_folder_is_refused_before_connecting(tmp_path):
    (tmp_path / "ds").mkdir()
    (tmp_path / "ds" / "notes.txt").write_text("mine")
    with pytest.raises(DatasetError, match="already exists and is not empty"):
        run_campaign(small(), RigConfig(), tmp_path / "ds", never_opened)
    assert [p.name for p in (tmp_path / "ds").iterdir()] == ["notes.txt"]


def test_the_simulated_rig_needs_the_samples_truth(tmp_path):
    campaign = small().model_copy(update={"sample": small().sample.model_copy(update={"simulated_brdf": None})})
    with pytest.raises(CampaignError, match="sample.simulated_brdf' is required on the simulated rig"):
        run_campaign(campaign, RigConfig(), tmp_path / "ds", never_opened, campaign_file="c.yaml")
    assert not (tmp_path / "ds").exists()


def test_a_campaign_without_a_measurable_point_is_refused(tmp_path):
    campaign = small(viewing=[{"centred_on": "normal", "theta": [89.9], "phi": [0]}])
    with pytest.raises(CampaignError, match="c.yaml: no point of the campaign can be measured"):
        run_campaign(campaign, RigConfig(), tmp_path / "ds", never_opened, campaign_file="c.yaml")


def _unfinished(tmp_path, status="interrupted"):
    """A dataset folder `rig run` left before its first point, and its campaign file."""
    campaign_file = tmp_path / "c.yaml"
    campaign_file.write_text(CAMPAIGN_YAML)
    campaign, rig = load_campaign(campaign_file), RigConfig()
    writer = DatasetWriter(tmp_path / "ds", manifest_for(campaign, campaign_file, rig))
    writer.update_manifest(status=status)
    writer.close()
    return tmp_path / "ds", campaign, campaign_file


def _files(folder):
    return {p.name: p.read_bytes() for p in folder.iterdir() if p.name != ".lock"}


def test_a_full_disk_is_refused_for_a_new_run_and_for_a_resume(tmp_path, monkeypatch):
    out, campaign, campaign_file = _unfinished(tmp_path)
    before = _files(out)
    monkeypatch.setattr(diskspace.shutil, "disk_usage", lambda path: Usage(10**9, 10**9 - 1000, 1000))
    with pytest.raises(DatasetError, match="not enough free disk space.*choose another --out"):
        run_campaign(campaign, RigConfig(), tmp_path / "other", never_opened, campaign_file=campaign_file)
    assert not (tmp_path / "other").exists()
    with pytest.raises(DatasetError, match="not enough free disk space.*move the folder to a disk with room"):
        resume_campaign(out, never_opened)
    assert _files(out) == before


def test_a_resume_passes_the_same_campaign_checks(tmp_path):
    """The resumed campaign is checked against the rig as a new run's is: here a campaign file changed (resumed
    with --force) to a drift limit within the meter's noise (rig.config.campaign.check_campaign_for_rig)."""
    out, _, campaign_file = _unfinished(tmp_path)
    before = _files(out)
    campaign_file.write_text(CAMPAIGN_YAML + "suspenders: {illuminance_drift_limit_rel: 0.00001}\n")
    with pytest.raises(CampaignError, match=f"(?s){campaign_file}: campaign does not fit the rig.*drift_limit_rel"):
        resume_campaign(out, never_opened, force=True)
    assert _files(out) == before


def test_a_complete_dataset_is_not_resumed(tmp_path):
    out, _, _ = _unfinished(tmp_path, status="complete")
    with pytest.raises(ResumeError, match="the campaign is complete; nothing to resume"):
        resume_campaign(out, never_opened)


def test_a_resume_removes_the_last_runs_phase(tmp_path):
    """Until the resumed run writes its own phase, the monitor goes by the events (the `resume` event: starting),
    not by the phase the last run ended in."""
    out, _, _ = _unfinished(tmp_path)
    (out / "phase.json").write_text('{"phase": "closing", "detail": "", "rig_time_s": 9.0, "time_utc": "x"}\n')

    def unreachable(campaign, rig):
        raise DeviceError("camera", "cannot connect: [Errno 111] Connection refused")
    outcome = resume_campaign(out, unreachable)
    assert (outcome.status, outcome.written) == ("failed", True) and not (out / "phase.json").exists()
