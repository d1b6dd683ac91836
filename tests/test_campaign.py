"""Campaign files: the shipped ones load; every bad file gives one message naming key, value, rule."""

from pathlib import Path

import pytest
import yaml

from rig.campaign import CampaignError, load_campaign, parse_campaign

ROOT = Path(__file__).resolve().parents[1]
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
    (variant(capture__roi_px=2), "capture.roi_px", "2", "greater than or equal to 4"),
    (variant(capture__exposure="auto"), "capture.exposure", None, "allowed here: roi_px"),
    (variant(colour="red"), "colour", None, "allowed here: name, sample"),
    (variant(sample__simulated_brdf__model="cook"), "sample.simulated_brdf.model", "'cook'", "retrophong"),
    (variant(sample__simulated_brdf__params={"kd": 0.5}), "sample.simulated_brdf", None, "missing n, k1"),
    (variant(sample__simulated_brdf__params__kd=float("nan")), "sample.simulated_brdf.params.kd", "nan", "finite"),
    (variant(incidence__0__theta=[float("inf")]), "incidence[0].theta[0]", "inf", "finite"),
    (variant(incidence=[]), "incidence", "[]", "at least 1"),
    ({k: v for k, v in GOOD.items() if k != "sample"}, "sample", None, "Field required"),
])
def test_bad_campaign_names_key_value_and_rule(data, key, value, rule):
    with pytest.raises(CampaignError) as err:
        parse_campaign(data, "bad.yaml")
    msg = str(err.value)
    assert msg.startswith("bad.yaml: invalid campaign")
    line = next(l for l in msg.splitlines() if f"'{key}'" in l)
    if value is not None:
        assert f"value {value}" in line
    assert rule in line


def test_malformed_yaml_names_line(tmp_path):
    f = tmp_path / "broken.yaml"
    f.write_text("name: x\nincidence: [ {phi: 0, theta: [0, 10}\n")
    with pytest.raises(CampaignError, match=r"broken.yaml: not valid YAML at line 2"):
        load_campaign(f)


@pytest.mark.parametrize("text, expected", [("", "got NoneType"), ("- 1\n- 2\n", "got list"),
                                            ("just a string", "got str")])
def test_not_a_mapping(tmp_path, text, expected):
    f = tmp_path / "c.yaml"
    f.write_text(text)
    with pytest.raises(CampaignError, match=expected):
        load_campaign(f)


def test_missing_file(tmp_path):
    with pytest.raises(CampaignError, match="campaign file not found"):
        load_campaign(tmp_path / "nope.yaml")


def test_yaml_tags_are_not_executed(tmp_path):
    f = tmp_path / "evil.yaml"
    f.write_text("name: !!python/object/apply:os.system ['true']\n")
    with pytest.raises(CampaignError, match="not valid YAML"):
        load_campaign(f)
