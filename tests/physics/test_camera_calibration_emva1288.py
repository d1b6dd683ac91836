"""The EMVA 1288 reference implementation (the `emva1288` package, EMVA's own) on the same simulated
frames as rig.physics.camera_calibration: DSNU, PRNU and linearity error agree.

Its system gain K cannot be compared: emva1288 1.0.2 fits it with `np.asfarray`, which NumPy 2 removed."""

import numpy as np
import pytest

from rig.config.rigfile import RigConfig
from rig.core.values import Window
from rig.physics import camera_calibration as cc
from rig.physics.brdf_models import get_model
from rig.simulators.camera import UniformSourceCamera
from rig.simulators.world import SimWorld

emva1288 = pytest.importorskip("emva1288")
from emva1288.process import routines  # noqa: E402
from emva1288.process.data import Data1288  # noqa: E402
from emva1288.process.results import Results1288  # noqa: E402

FRAMES = 8
#: Photons per pixel per second of exposure: any constant, the sweep is in exposure time (EMVA allows it).
PHOTONS_PER_S = 1.0e5


def frames_of(nonlinearity_rel: float):
    """Stacks (light, dark) per exposure of a 160×120 camera with a 50 mm lens (no fall-off to speak of,
    since EMVA's PRNU includes it) looking at a uniform source, and the exposures."""
    config = RigConfig.model_validate({"camera": {"width_px": 160, "height_px": 120},
                                       "simulation": {"seed": 11, "dsnu_e_s": 200.0,
                                                      "nonlinearity_rel": nonlinearity_rel}})
    cam = UniformSourceCamera(SimWorld(config, get_model("lambert"), {"kd": 0.5}), 100.0)
    exposures = np.linspace(0.006, 0.19, 12)
    light = [np.stack([cam.capture(t).pixels_dn for _ in range(FRAMES)]) for t in exposures]
    dark = [np.stack([cam.capture_dark(t).pixels_dn for _ in range(FRAMES)]) for t in exposures]
    return exposures, light, dark


def emva_results(exposures, light, dark, spatial_index):
    temporal = {}
    for t, li, di in zip(exposures, light, dark, strict=True):
        pair = {}
        for photons, stack in ((0.0, di), (t * PHOTONS_PER_S, li)):
            imgs = routines.get_int_imgs(list(stack[:2]))
            pair[photons] = {"sum": np.sum(imgs["sum"]), "pvar": np.sum(imgs["pvar"]), "dmean": imgs["dmean"]}
        temporal[t] = pair
    t = exposures[spatial_index]
    spatial = {t: {0.0: routines.get_int_imgs(list(dark[spatial_index])),
                   t * PHOTONS_PER_S: routines.get_int_imgs(list(light[spatial_index]))}}
    data = Data1288({"width": 160, "height": 120, "temporal": temporal, "spatial": spatial})
    return Results1288(data.data, loglevel=40)


def ours(exposures, light, dark, spatial_index):
    flats = [cc.stack_stats(s) for s in light]
    darks = [cc.stack_stats(s) for s in dark]
    signal = np.array([(f.mean_dn - d.mean_dn).mean() for f, d in zip(flats, darks, strict=True)])
    u = np.array([np.sqrt((f.var_of_mean_dn2 + d.var_of_mean_dn2) / f.mean_dn.size)
                  for f, d in zip(flats, darks, strict=True)])
    lin = cc.linearity(exposures, signal, u, signal.max())
    flat = cc.flat_field(flats[spatial_index], darks[spatial_index], Window.centred(160, 120, 40, 40))
    return lin, flat, cc.dark_level(darks[spatial_index], exposures[spatial_index])


@pytest.fixture(scope="module")
def linear():
    exposures, light, dark = frames_of(0.0)
    return emva_results(exposures, light, dark, 6), ours(exposures, light, dark, 6)


def test_dsnu_and_prnu_agree_with_the_reference(linear):
    ref, (_, flat, dark) = linear
    assert dark.dsnu_dn == pytest.approx(ref.DSNU1288_DN(), rel=1e-6)      # the same formula
    assert flat.prnu_rel == pytest.approx(ref.PRNU1288 / 100, rel=0.01)


def test_linearity_error_agrees_with_the_reference():
    exposures, light, dark = frames_of(0.03)
    ref = emva_results(exposures, light, dark, 6)
    lin, _, _ = ours(exposures, light, dark, 6)
    le_ref = (ref.LE_max - ref.LE_min) / 2
    assert le_ref > 0.3                                       # the nonlinearity is there for both to see
    assert lin.le_percent == pytest.approx(le_ref, rel=0.01)
