"""Malformed attenuator and uncertainty_not_stated entries in a real rig file are named by the validation,
not crashed on by the pass that records unstated calibration u (found by test_config_fuzz: filters: [null])."""

import pytest

from rig.config.rigfile import RigConfig
from rig.config.stated_u import unstated_u


@pytest.mark.parametrize("filters", [[None], 5, ["x"], [{"position": 2, "transmission": 0.1}]])
def test_malformed_filters_are_passed_over(filters):
    data = {"simulated": False, "attenuator": {"filters": filters}, "uncertainty_not_stated": 7}
    missing = unstated_u(data)
    assert "camera.calibration_u_rel" in missing and "meter.calibration_u_rel" in missing


def test_a_null_filter_gives_a_validation_error_not_an_attribute_error():
    with pytest.raises(ValueError):      # pydantic's ValidationError is a ValueError
        RigConfig.model_validate({"simulated": False, "attenuator": {"filters": [None]}})
