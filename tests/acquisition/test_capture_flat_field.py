"""A camera with a calibration file: a raw acquisition's `reduce()` divides its flat field out of the merged
rate, for the ROI and for the full frame, so a uniform source reads uniform whatever the fall-off and PRNU."""

import dataclasses

import pytest

from rig.acquisition.capture import RawCapturer
from rig.config.capture import CaptureSettings
from rig.config.rigfile import RigConfig
from rig.physics.brdf_models import get_model
from rig.physics.camera_calibration import CalibratedSensorInfo
from rig.simulators.camera import UniformSourceCamera
from rig.simulators.world import SimWorld

L_CD_M2 = 100.0


def camera(calibrated: bool) -> UniformSourceCamera:
    """A short-lens 160×120 camera before a uniform source; if `calibrated`, with its true flat field
    and coefficient as a calibration file would give them."""
    config = RigConfig.model_validate({"camera": {"width_px": 160, "height_px": 120, "focal_length_mm": 8.0},
                                       "simulation": {"seed": 2}})
    cam = UniformSourceCamera(SimWorld(config, get_model("lambert"), {"kd": 0.5}), L_CD_M2)
    if calibrated:
        fields = {f.name: getattr(cam.sensor, f.name) for f in dataclasses.fields(cam.sensor)}
        cam.sensor = CalibratedSensorInfo(**{**fields, "calibration_u_rel": 0.01},
                                          flat_field=cam.model.gain * cam.model.illumination)
    return cam


@pytest.mark.parametrize("full_frame", [False, True])
def test_flat_field_divided_out(full_frame):
    settings = CaptureSettings(roi_px=40, full_frame=full_frame, frames_per_exposure=4, max_frames=4,
                               dark_max_age_s=None)
    plain, calibrated = (RawCapturer(camera(c), settings).acquire().reduce() for c in (False, True))
    assert calibrated.luminance_cd_m2 == pytest.approx(L_CD_M2, rel=3 * calibrated.u_noise_cd_m2 / L_CD_M2)
    assert calibrated.u_luminance_cd_m2 >= 0.01 * calibrated.luminance_cd_m2
    assert calibrated.roi_std_cd_m2 < plain.roi_std_cd_m2          # PRNU and fall-off gone
    if full_frame:
        image, raw = calibrated.image_cd_m2, plain.image_cd_m2
        corners = (slice(0, 10), slice(0, 10))
        assert raw[corners].mean() < 0.99 * L_CD_M2               # the uncorrected corner falls off
        assert image[corners].mean() == pytest.approx(L_CD_M2, rel=2e-3)
        assert image.std() < 0.75 * raw.std()                      # what is left is mostly shot noise
