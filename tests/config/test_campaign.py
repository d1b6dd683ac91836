"""Campaign files: the shipped ones load; every bad file gives one message naming key, value, rule."""


import pytest
import yaml

from repo_paths import ROOT
from rig.config.campaign import CampaignError, load_campaign, parse_campaign

GOOD = yaml.safe_load((ROOT / "campaigns" / "quick.yaml").read_text())


def variant(**changes):
    data = yaml.safe_load(yaml.safe_dump(GOOD))
    for dotted, value in changes.items():
        node = data
        *parents, last = dotted.split("__")
        for key in parents:
            node = node[int(key)] if key.isdigit() else node.setdefault(key, {})
        node[int(last) if last.isdigit() else last] = value
    return data


@pytest.mark.parametrize("path", sorted((ROOT / "campaigns").glob("*.yaml")))
def test_shipped_campaigns_load(path):
    campaign = load_campaign(path)
    assert campaign.sample.simulated_brdf is not None


def test_contract_example_keys():
    c = load_campaign(ROOT / "campaigns" / "spieringhs2023-rm1.yaml")
    assert [s.phi for s in c.incidence] == [0, 23, 45]
    assert c.viewing[0].centred_on == "incidence" and len(c.viewing[0].phi) == 14
    assert c.output.dir == "runs/spieringhs2023-rm1"
    assert c.capture.roi_px == 70


@pytest.mark.parametrize("data, key, value, rule", [
    (variant(incidence__0__theta=[0, 95]), "incidence[0].theta[1]", "95", "less than 90"),
    (variant(incidence__0__phi=-5), "incidence[0].phi", "-5", "greater than or equal to 0"),
    (variant(viewing__0__centred_on="incidnce"), "viewing[0].centred_on", "'incidnce'", "'mirror'"),
    (variant(viewing__0__theta=["ten"]), "viewing[0].theta[0]", "'ten'", "number"),
    (variant(capture__roi_px=2), "capture.roi_px", "2", "greater than or equal to 20"),
    (variant(capture__exposure="auto"), "capture.exposure", None, "allowed here: roi_px"),
    (variant(colour="red"), "colour", None, "allowed here: name, sample"),
    (variant(sample__simulated_brdf__model="cook"), "sample.simulated_brdf.model", "'cook'", "retrophong"),
    (variant(sample__simulated_brdf__params={"kd": 0.5}), "sample.simulated_brdf", None, "missing n, k1"),
    (variant(sample__simulated_brdf__params__kd=float("nan")), "sample.simulated_brdf.params.kd", "nan", "finite"),
    (variant(incidence__0__theta=[float("inf")]), "incidence[0].theta[0]", "inf", "finite"),
    (variant(incidence=[]), "incidence", "[]", "at least 1"),
    ({k: v for k, v in GOOD.items() if k != "sample"}, "sample", None, "missing key 'sample'"),
])
def test_bad_campaign_names_key_value_and_rule(data, key, value, rule):
    with pytest.raises(CampaignError) as err:
        parse_campaign(data, "bad.yaml")
    msg = str(err.value)
    assert msg.startswith("bad.yaml: invalid campaign")
    line = next(text for text in msg.splitlines() if f"'{key}'" in text)
    if value is not None:
        assert f"value {value}" in line
    assert rule in line


def test_malformed_yaml_names_line(tmp_path):
    f = tmp_path / "broken.yaml"
    f.write_text("name: x\nincidence: [ {phi: 0, theta: [0, 10}\n")
    with pytest.raises(CampaignError, match=r"broken.yaml: not valid YAML at line 2"):
        load_campaign(f)


def test_missing_file(tmp_path):
    with pytest.raises(CampaignError, match="campaign file not found"):
        load_campaign(tmp_path / "nope.yaml")


def test_yaml_tags_are_not_executed(tmp_path):
    f = tmp_path / "evil.yaml"
    f.write_text("name: !!python/object/apply:os.system ['true']\n")
    with pytest.raises(CampaignError, match="not valid YAML"):
        load_campaign(f)


# -- bounded reading and messages (issue 9) ------------------------------------------------------
def _bomb(levels: int = 9) -> str:
    """A YAML alias bomb: `sample: *x` stands for 9^levels strings, in about 40 bytes a level."""
    names = [f"l{i}" for i in range(levels)]
    lines = [f"{names[0]}: &{names[0]} [" + ",".join(['"lol"'] * 9) + "]"]
    lines += [f"{n}: &{n} [" + ",".join([f"*{p}"] * 9) + "]" for p, n in zip(names, names[1:])]
    return "\n".join(lines) + f"\nname: x\nsample: *{names[-1]}\n"


def test_alias_bomb_is_refused_with_a_short_message(tmp_path):
    f = tmp_path / "bomb.yaml"
    f.write_text(_bomb())
    with pytest.raises(CampaignError, match=r"refused at line \d+.*aliases expanded") as err:
        load_campaign(f)
    assert len(str(err.value)) < 300


def test_alias_within_bounds_is_read_but_never_printed_whole(tmp_path):
    """A small expansion is allowed (anchors are ordinary YAML); the message shows a short value."""
    f = tmp_path / "c.yaml"
    f.write_text(_bomb(levels=4))        # 9^4 strings: within the bound
    with pytest.raises(CampaignError, match="sample") as err:
        load_campaign(f)
    assert len(str(err.value)) < 1000


@pytest.mark.parametrize("text, expected", [
    ("", "got NoneType"),                                   # not a mapping
    ("- 1\n- 2\n", "got list"),
    ("just a string", "got str"),
    ("name: &a [1, *a]\n", "refers to the mapping or list that contains it"),
    ("name: " + "[" * 200 + "]" * 200 + "\n", "nested deeper than"),
    ("name: !!float x\n", "not valid YAML"),
    ("name: " + "9" * 5000 + "\n", "not valid YAML"),
])
def test_pathological_yaml_is_refused(tmp_path, text, expected):
    f = tmp_path / "c.yaml"
    f.write_text(text)
    with pytest.raises(CampaignError, match=expected):
        load_campaign(f)


def test_oversized_file_is_refused(tmp_path):
    f = tmp_path / "big.yaml"
    f.write_text("name: x\n" + "#" * (2 << 20) + "\n")
    with pytest.raises(CampaignError, match="larger than"):
        load_campaign(f)


def test_duplicate_key_is_refused_with_its_lines(tmp_path):
    f = tmp_path / "dup.yaml"
    f.write_text((ROOT / "campaigns" / "quick.yaml").read_text() + "name: again\n")
    with pytest.raises(CampaignError, match=r"key 'name' given twice \(lines 3 and \d+\)"):
        load_campaign(f)


def test_merge_keys_may_override_without_counting_as_duplicates(tmp_path):
    f = tmp_path / "c.yaml"
    f.write_text((ROOT / "campaigns" / "quick.yaml").read_text().replace(
        "lamp:\n  warmup_min_s: 300\n", "base: &b {warmup_min_s: 300, warmup_check_s: 30}\n"
        "lamp: {<<: *b, warmup_min_s: 120}\n"))
    with pytest.raises(CampaignError) as err:          # only the anchor's holder is unknown
        load_campaign(f)
    assert str(err.value).count("\n") == 1 and "unknown key 'base'" in str(err.value)


def test_missing_key_names_the_path_without_the_input():
    """Before: a missing key printed its whole parent mapping (the whole file for `name`)."""
    data = variant()
    del data["name"]
    del data["sample"]["id"]
    with pytest.raises(CampaignError) as err:
        parse_campaign(data, "bad.yaml")
    msg = str(err.value)
    assert "missing key 'name'" in msg and "missing key 'sample.id'" in msg
    assert "retrophong" not in msg and "incidence" not in msg


def test_long_values_are_shortened_in_messages():
    msg = str(pytest.raises(CampaignError, parse_campaign, variant(ordering="x" * 10_000), "bad.yaml").value)
    assert max(map(len, msg.splitlines())) < 300


def test_many_problems_are_counted_not_listed():
    msg = str(pytest.raises(CampaignError, parse_campaign,
                            variant(incidence__0__theta=["a"] * 500), "bad.yaml").value)
    assert "… and 480 more" in msg and len(msg.splitlines()) == 22


@pytest.mark.parametrize("data, key", [
    (variant(incidence__0__phi=360), "incidence[0].phi"),
    (variant(viewing=[{"points": [[20, 360]]}]), "viewing[0].points[0][1]"),
    (variant(lamp__warmup_min_s=1e308), "lamp.warmup_min_s"),
    (variant(lamp__warmup_max_s=1e308), "lamp.warmup_max_s"),
    (variant(lamp__warmup_check_s=1e-300), "lamp.warmup_check_s"),
    (variant(lamp__warmup_min_s=600, lamp__warmup_max_s=300), "lamp"),
    (variant(suspenders__max_wait_s=1e9), "suspenders.max_wait_s"),
    (variant(suspenders__check_interval_s=1e-9), "suspenders.check_interval_s"),
    (variant(capture__probe_exposure_s=1e308), "capture.probe_exposure_s"),
    (variant(capture__dark_max_age_s=float("inf")), "capture.dark_max_age_s"),
    (variant(name="two\nlines"), "name"),
    (variant(output__dir="runs/\x00"), "output.dir"),
    (variant(incidence=[{"phi": 0, "theta": list(range(0, 90, 1))}] * 2,
             viewing=[{"points": [[10, p] for p in range(0, 359)] * 2}]), "(top level)"),
])
def test_time_angle_and_size_bounds(data, key):
    with pytest.raises(CampaignError) as err:
        parse_campaign(data, "bad.yaml")
    assert f"'{key}'" in str(err.value)


def test_pattern_phi_360_is_the_contracts_example():
    """Azimuths around a pattern's centre may be 360 (the contract's Table 2); SCS azimuths may not."""
    assert parse_campaign(variant(viewing__0__phi=[90, 360])).viewing[0].phi == [90, 360]


def test_drift_limit_below_the_meter_noise_is_refused():
    """Before: a limit below the meter's repeatability discarded and re-took points without end."""
    from rig.config.campaign import check_campaign_for_rig
    from rig.config.rigfile import RigConfig

    rig = RigConfig()            # repeatability 0.002: two 5-reading means differ by 0.13 % (1σ)
    check_campaign_for_rig(parse_campaign(variant()), rig)
    noisy = parse_campaign(variant(suspenders={"illuminance_drift_limit_rel": 0.001}))
    with pytest.raises(CampaignError, match=r"'suspenders.illuminance_drift_limit_rel'.*must exceed 0.0063"):
        check_campaign_for_rig(noisy, rig, "bad.yaml")
    averaged = parse_campaign(variant(suspenders={"illuminance_drift_limit_rel": 0.001},
                                      illuminance={"readings": 1000}))
    check_campaign_for_rig(averaged, rig)     # 1000 readings: 5σ = 0.045 %


def test_roi_larger_than_the_sensor_is_refused():
    from rig.config.campaign import check_campaign_for_rig
    from rig.config.rigfile import CameraConfig, RigConfig

    small = RigConfig(camera=CameraConfig(width_px=640, height_px=480))
    with pytest.raises(CampaignError, match="'capture.roi_px'.*640×480"):
        check_campaign_for_rig(parse_campaign(variant(capture={"roi_px": 500})), small, "c.yaml")
