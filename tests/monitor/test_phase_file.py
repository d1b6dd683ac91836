"""The run's phase written by the engine (phase.json, rig.acquisition.phase) and read by the monitor
(rig.monitor.phase) instead of being worked out from the kinds of the events; an older folder without it is
followed as before (tests/monitor/test_folder.py)."""

from __future__ import annotations

import json

from shared import Folder, warm

from rig.acquisition.run import run_campaign
from rig.config.campaign import parse_campaign
from rig.config.rigfile import RigConfig
from rig.session.connect import open_campaign_rig


def write_phase(folder: Folder, phase: str, detail: str = "") -> None:
    tmp = folder.path / "phase.json.tmp"
    tmp.write_text(json.dumps({"phase": phase, "detail": detail, "rig_time_s": 1.0, "time_utc": "x"}) + "\n")
    tmp.replace(folder.path / "phase.json")


def test_the_monitor_shows_the_phase_the_run_wrote(tmp_path):
    f = Folder(tmp_path / "ds")
    warm(f)
    assert f.look()["phase"] == "measuring"                          # no phase.json: the events' phase
    write_phase(f, "paused", "meter: no reply")
    assert (f.look()["phase"], f.look()["detail"]) == ("paused", "meter: no reply")
    write_phase(f, "measuring")
    assert (f.look()["phase"], f.look()["detail"]) == ("measuring", "")
    f.set_manifest(status="interrupted")
    assert f.look()["phase"] == "interrupted"                        # how the run ended is the manifest's


def test_a_phase_file_that_cannot_be_read_leaves_the_events_phase_with_a_warning(tmp_path):
    f = Folder(tmp_path / "ds")
    warm(f)
    (f.path / "phase.json").write_text('{"phase": "dancing", "detail": ""}\n')
    s = f.look()
    assert s["phase"] == "measuring" and any("phase.json: not a phase record" in w for w in s["warnings"])
    (f.path / "phase.json").write_text('{"phase": "paused", "detail": ')
    s = f.look()
    assert s["phase"] == "measuring" and any(w.startswith("phase.json:") for w in s["warnings"])
    write_phase(f, "stopping", "Ctrl+C")
    s = f.look()
    assert (s["phase"], s["detail"]) == ("stopping", "Ctrl+C") and not any("phase.json" in w for w in s["warnings"])


def test_a_run_writes_its_phase_as_it_goes(tmp_path):
    campaign = parse_campaign({
        "name": "small", "sample": {"id": "S", "simulated_brdf": {"model": "lambert", "params": {"kd": 0.5}}},
        "incidence": [{"phi": 0, "theta": [0]}], "viewing": [{"centred_on": "normal", "theta": [10, 30], "phi": [0]}],
        "lamp": {"warmup_min_s": 60}})
    out, seen = tmp_path / "ds", []

    def note(progress) -> None:
        if (out / "phase.json").exists():
            phase = json.loads((out / "phase.json").read_text())["phase"]
            if not seen or seen[-1] != phase:
                seen.append(phase)
    outcome = run_campaign(campaign, RigConfig(), out, open_campaign_rig, progress=note)
    assert outcome.status == "complete", outcome.error
    assert seen[:2] == ["warm-up", "measuring"]
    assert json.loads((out / "phase.json").read_text())["phase"] == "closing"
    assert not (out / "phase.json.tmp").exists()
