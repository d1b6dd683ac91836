"""Simulated camera, sensor model and sample texture against closed-form expectations.

The camera's speed is a benchmark (benchmarks/hot_paths.py), not a test.
"""

import numpy as np
import pytest

from rig.config.rigfile import CameraConfig, RigConfig, SimulationConfig
from rig.core.errors import DeviceError
from rig.core.values import Window
from rig.physics.brdf_models import get_model
from rig.physics.geometry import AXIS_NAMES, directions_scs, forward_deg, inverse_deg, sample_frame
from rig.physics.optics import in_beam, intersect_sample_plane, pixel_rays
from rig.simulators.axis_model import AxisModel
from rig.simulators.camera import SimCamera, lit_view
from rig.simulators.sensor import SensorModel, digitise, electrons
from rig.simulators.texture import GlintTexture, ValueNoiseTexture
from rig.simulators.world import SimWorld

#: Settings that remove every random or drifting effect except shot noise.
QUIET = dict(texture_contrast=0.0, glint_contrast=0.0, prnu_rel=0.0, dsnu_e_s=0.0, dark_current_e_s=0.0,
             warmup_amplitude=0.0, drift_per_hour=0.0)
PX_ON_SAMPLE = 6.45e-6 * 1.54 / 0.05          # one pixel on a fronto-parallel sample (m)
ROI = Window.centred(1390, 1040, 100, 100)


def make_camera(model="lambert", params=None, angles=(30, 0, 20, 90), camera=None, **sim):
    """A lit simulated rig posed at BRDF angles (θi, φi, θo, φo) in degrees."""
    cfg = RigConfig(camera=camera or CameraConfig(), simulation=SimulationConfig(**sim))
    world = SimWorld(cfg, get_model(model), params or {"kd": 0.5})
    world.lamp.set_current(cfg.lamp.current_a, 0)
    world.lamp.switch(True)
    pose(world, *angles)
    return SimCamera(world)


def pose(world, *angles_deg):
    set_motors(world, inverse_deg(*angles_deg).as_array())


def set_motors(world, motors_deg):
    for name, value in zip(AXIS_NAMES, motors_deg):
        world.axis_truth[name] = lambda value=float(value): value


def to_luminance(cam, frame):
    sensor = cam.sensor
    return (frame.pixels_dn - sensor.black_level_dn) * sensor.calibration_cd_m2_per_dn_s / frame.exposure_s


# --- rendering ---------------------------------------------------------------------------

def test_lambertian_sample_renders_kd_over_pi_times_e_cos_theta_i():
    cam = make_camera(camera=CameraConfig(read_noise_e=0.0), **QUIET)
    e_normal = cam.world.illuminance_normal_lx()
    expected = 0.5 / np.pi * e_normal * np.cos(np.radians(30))
    np.testing.assert_allclose(cam.luminance(ROI, e_normal), expected, rtol=1e-12)

    exposure = 9000 / (expected * 900)                                 # half the full well
    frame = cam.capture(exposure, ROI)
    assert frame.pixels_dn.dtype == np.uint16 and frame.pixels_dn.shape == (100, 100)
    assert to_luminance(cam, frame).mean() == pytest.approx(expected, rel=1e-3)
    k = cam.sensor.gain_dn_per_e
    expected_dn = 64 + k * 9000
    assert np.abs(frame.pixels_dn - expected_dn).max() <= 0.5 + 5 * k * np.sqrt(9000)


def test_render_uses_scs_directions_of_the_pixel():
    params = {"kd": 0.2, "ks": 0.5, "n": 40.0}
    angles = (35, 20, 30, 190)                                         # near the specular lobe
    cam = make_camera("modified_phong", params, angles, **QUIET)
    lum = cam.luminance(Window.centred(1390, 1040, 2, 2), 1000.0)      # pixels round the axis
    wi, wo = directions_scs(*np.radians(inverse_deg(*angles).as_array()))
    f = get_model("modified_phong")(wi, wo, params)
    np.testing.assert_allclose(lum, f * 1000.0 * wi[2], rtol=2e-3)
    full = cam.luminance(cam.full_window(), 1000.0)
    assert full.max() > 1.2 * full[full > 0].min()                     # ωo varies per pixel


def test_rendered_footprint_is_ellipse_r_by_r_over_cos_theta_i():
    cam = make_camera(angles=(60, 0, 0, 0), **QUIET)                   # camera on the normal
    lit = cam.luminance(cam.full_window(), 5000.0) > 0
    rows = np.flatnonzero(lit.any(axis=1))
    cols = np.flatnonzero(lit.any(axis=0))
    semi_axes = np.array([rows.size, cols.size]) * PX_ON_SAMPLE / 2
    np.testing.assert_allclose(semi_axes, [0.0375 / np.cos(np.radians(60)), 0.0375], atol=PX_ON_SAMPLE)


def test_outside_the_spot_is_ambient_and_a_dark_lamp_is_dark():
    cam = make_camera(ambient_cd_m2=3.0, **QUIET)
    lum = cam.luminance(cam.full_window(), 5000.0)
    ambient = np.isclose(lum, 3.0, rtol=1e-12, atol=0)
    assert ambient[0, 0] and ambient.mean() > 0.5
    for name, deg in zip(AXIS_NAMES, (100.0, 0.0, 10.0, 90.0)):        # lamp behind the sample
        cam.world.axis_truth[name] = lambda deg=deg: deg
    np.testing.assert_allclose(cam.luminance(cam.full_window(), 5000.0), 3.0, rtol=1e-12, atol=0)
    pose(cam.world, 30, 0, 20, 90)
    cam.world.lamp.switch(False)
    lum_off = cam.luminance(cam.full_window(), cam.world.illuminance_normal_lx())
    dark, ambient = np.isclose(lum_off, 0.0, rtol=0, atol=1e-12), np.isclose(lum_off, 3.0, rtol=1e-12, atol=0)
    assert np.all(dark | ambient) and dark.any() and ambient.any()     # nothing but black and ambient


def test_windowed_render_equals_the_full_frame_pixels():
    cam = make_camera(angles=(50, 30, 40, 200))                        # textured sample
    full = cam.luminance(cam.full_window(), 5000.0)
    window = Window(300, 200, 400, 333)
    part = cam.luminance(window, 5000.0)
    np.testing.assert_allclose(part, full[cam.full_window().inner(window)], rtol=1e-12)
    assert 0 < (part > 0).mean() < 1                                   # straddles the spot edge


def test_camera_renders_the_physical_angles_not_the_read_back():
    """The axes meet at the sample centre, so zero errors barely move the image: they show as angle errors."""
    cam = make_camera(**QUIET)                                         # default zero errors: σ = 0.01°
    world = cam.world
    axes = [AxisModel(world, name, getattr(world.config.axes, name), steps_per_degree=1000) for name in AXIS_NAMES]
    for axis, target in zip(axes, inverse_deg(60, 0, 20, 90).as_array()):
        axis.start_move(float(target), 20.0, 40.0)
    world.clock.sleep(30.0)
    physical = [axis.encoder_position_deg() + axis.zero_offset_deg for axis in axes]
    read_back = [axis.state().encoder_steps / 1000 for axis in axes]
    assert world.motor_angles_deg() == pytest.approx(physical, abs=1e-12)

    def lambertian_luminance(motors):
        return 0.5 / np.pi * 1000.0 * np.cos(np.radians(forward_deg(*motors).theta_i_deg))

    np.testing.assert_allclose(cam.luminance(ROI, 1000.0), lambertian_luminance(physical), rtol=1e-9)
    assert abs(lambertian_luminance(read_back) / lambertian_luminance(physical) - 1) > 1e-4


def test_illuminance_is_taken_at_mid_exposure():
    cam = make_camera(camera=CameraConfig(read_noise_e=0.0), **{
        **QUIET, "illuminance_normal_lx": 10.0, "warmup_amplitude": -0.2, "warmup_tau_s": 20.0})
    frame = cam.capture(4.0, ROI)
    e_mid = cam.world.illuminance_normal_lx(2.0)
    assert cam.world.illuminance_normal_lx(0.0) < 0.98 * e_mid         # the test can tell
    expected = 0.5 / np.pi * e_mid * np.cos(np.radians(30))
    assert to_luminance(cam, frame).mean() == pytest.approx(expected, rel=1e-3)


# --- sensor ------------------------------------------------------------------------------

def test_photon_transfer_follows_emva_1288():
    cam = make_camera(angles=(0, 0, 10, 90), texture_contrast=0.0, glint_contrast=0.0, warmup_amplitude=0.0,
                      drift_per_hour=0.0)
    flat = Window.centred(1390, 1040, 200, 200)
    k, t = cam.sensor.gain_dn_per_e, 0.05

    def mean_and_temporal_var(capture):
        y1, y2 = (capture(t, flat).pixels_dn.astype(float) for _ in range(2))
        return (y1.mean() + y2.mean()) / 2, np.var(y1 - y2) / 2

    mu_dark, var_dark = mean_and_temporal_var(cam.capture_dark)
    sigma_d2 = 8.0 ** 2 + 20.0 * t                                     # read noise + dark shot noise
    assert var_dark == pytest.approx(k ** 2 * sigma_d2 + 1 / 12, rel=0.05)
    electrons_per_kd = 900 * t * cam.world.illuminance_normal_lx() / np.pi   # θi = 0
    for fill in (0.1, 0.4, 0.8):                                       # of the full well
        cam.world.brdf_params = {"kd": fill * 18000 / electrons_per_kd}
        mu_y, var_y = mean_and_temporal_var(cam.capture)
        assert mu_y - mu_dark == pytest.approx(k * fill * 18000, rel=0.01)
        assert var_y == pytest.approx(var_dark + k * (mu_y - mu_dark), rel=0.03)


def test_saturation_clips_at_the_adc_maximum():
    cam = make_camera(camera=CameraConfig(read_noise_e=200.0))         # noise cannot unsaturate
    frame = cam.capture(2.0, ROI)
    assert (frame.pixels_dn == 4095).all()
    assert cam.sensor.saturation_dn == 4095


def test_charge_is_clipped_at_the_full_well():
    rng = np.random.default_rng(0)
    charge = electrons(rng, np.array([1e5, 1e12, 100.0]), 8.0, 18000.0)
    assert charge[0] == charge[1] == 18000.0 and abs(charge[2] - 100) < 60


def test_prnu_shapes_a_flat_field():
    cam = make_camera(angles=(0, 0, 10, 90), **{**QUIET, "prnu_rel": 0.05})
    flat = Window.centred(1390, 1040, 200, 200)
    signal = cam.capture(0.0125, flat).pixels_dn - 64.0                # ≈ 9000 e⁻
    mean_e = signal.mean() / cam.sensor.gain_dn_per_e
    assert signal.std() / signal.mean() == pytest.approx(np.hypot(0.05, 1 / np.sqrt(mean_e)), rel=0.05)
    pattern = cam.model.gain[cam.full_window().inner(flat)]
    assert np.corrcoef(signal.ravel(), pattern.ravel())[0, 1] > 0.95


def test_dark_frame_mean_is_black_level_plus_dark_current():
    cam = make_camera()
    frame = cam.capture_dark(10.0, Window.centred(1390, 1040, 200, 200))
    assert frame.dark and frame.exposure_s == 10.0
    k = cam.sensor.gain_dn_per_e
    assert frame.pixels_dn.mean() == pytest.approx(64 + k * 20.0 * 10.0, abs=0.15)


def test_fixed_patterns_belong_to_the_sensor_not_the_window():
    model = SensorModel.from_config(CameraConfig(), SimulationConfig(prnu_rel=0.05, dsnu_e_s=5.0),
                                    np.random.default_rng(0))
    full = Window(0, 0, 1390, 1040)
    window = Window(17, 900, 64, 40)
    np.testing.assert_allclose(model.mean_electrons(3.0, 0.2, window),
                               model.mean_electrons(3.0, 0.2, full)[full.inner(window)], rtol=1e-12, atol=0)
    assert model.gain.std() == pytest.approx(0.05, rel=0.01)
    assert model.dark_e_s.std() == pytest.approx(5.0, rel=0.01)


def test_digitise_rounds_offsets_and_clips():
    dn = digitise(np.array([-1e3, 0.0, 10.0, 1e9]), 0.5, 64.0, 12)
    np.testing.assert_array_equal(dn, [0, 64, 69, 4095])
    assert dn.dtype == np.uint16


def test_enormous_luminance_saturates_without_error():
    model = SensorModel.from_config(CameraConfig(), SimulationConfig(), np.random.default_rng(0))
    dn = model.read(np.random.default_rng(1), 1e30, 15.0, Window(0, 0, 8, 8))
    assert (dn == 4095).all()


# --- timing and the interface ------------------------------------------------------------

def test_clock_advances_by_exposure_and_readout():
    cam = make_camera()
    clock = cam.world.clock
    start = clock.now()
    assert cam.capture(0.25).exposure_s == 0.25
    assert clock.now() - start == pytest.approx(0.25 + 0.1)
    start = clock.now()
    cam.capture_dark(0.5, Window(0, 0, 139, 104))
    assert clock.now() - start == pytest.approx(0.5 + 0.1 / 100)


def test_exposure_is_clamped_to_the_sensor_range():
    cam = make_camera()
    assert cam.capture(1e-9, ROI).exposure_s == cam.sensor.min_exposure_s
    start = cam.world.clock.now()
    assert cam.capture_dark(100.0, ROI).exposure_s == cam.sensor.max_exposure_s
    assert cam.world.clock.now() - start == pytest.approx(15.0 + 0.1 * 1e4 / (1390 * 1040))


def test_bad_requests_raise_device_errors():
    cam = make_camera()
    with pytest.raises(DeviceError):
        cam.capture(0.1, Window(1300, 0, 100, 10))
    with pytest.raises(DeviceError):
        cam.capture(float("nan"), ROI)
    assert "sim" in cam.identity()


# --- texture -----------------------------------------------------------------------------

def test_texture_has_unit_mean_and_the_expected_spatial_std():
    texture = ValueNoiseTexture(contrast=0.1, grain_m=1e-3, seed=7)
    step = 0.37e-3                                                     # incommensurate with the grain
    x, y = np.meshgrid(np.arange(800) * step, np.arange(800) * step - 0.1)
    values = texture(x, y)
    # Independent lattice values blended with smoothstep weights w: E[Σw²] = (26/35)² in 2-D.
    assert values.mean() == pytest.approx(1.0, abs=2e-3)
    assert values.std() == pytest.approx(0.1 * 26 / 35, rel=0.03)
    assert values.min() > 0


def test_texture_lattice_values_are_lognormal_with_mean_one():
    texture = ValueNoiseTexture(contrast=0.3, grain_m=1e-3, seed=1)
    ix, iy = np.meshgrid(np.arange(-250, 250), np.arange(400))
    nodes = texture.lattice(ix, iy)
    assert nodes.mean() == pytest.approx(1.0, abs=3e-3)
    assert nodes.std() == pytest.approx(0.3, rel=0.02)
    assert np.log(nodes).std() == pytest.approx(np.sqrt(np.log1p(0.09)), rel=0.02)
    np.testing.assert_allclose(texture(ix[:3, :3] * 1e-3, iy[:3, :3] * 1e-3), nodes[:3, :3], rtol=1e-12)


def test_texture_expectation_is_one_at_any_point_and_direction():
    wi, wo = directions_scs(*np.radians([35.0, 0.0, 20.0, 170.0]))
    static, glint = np.array([(ValueNoiseTexture(0.2, 1e-3, seed)(0.00031, -0.00077),
                               GlintTexture(0.2, 5e-4, np.radians(2), seed)(0.00031, -0.00077, wi, wo))
                              for seed in range(4000)]).T
    bound = 3 * 0.2 / np.sqrt(4000)
    assert static.mean() == pytest.approx(1.0, abs=bound)
    assert glint.mean() == pytest.approx(1.0, abs=bound)
    assert abs(np.corrcoef(static, glint)[0, 1]) < 4 / np.sqrt(4000)        # independent factors ...
    assert (static * glint).mean() == pytest.approx(1.0, abs=1.5 * bound)   # ... so the product's mean is 1


def test_static_texture_is_the_one_of_the_glint_free_simulator():
    """Values pinned before the glints were added: seeded samples keep their static texture."""
    for (seed, contrast, x, y), value in {(1, 0.1, 0.00031, -0.00077): 0.9733963601803981,
                                          (3, 0.3, -0.0123, 0.0456): 0.8014785460459579,
                                          (7, 0.03, 0.25, -0.125): 1.040457638481475}.items():
        assert ValueNoiseTexture(contrast, 1e-3, seed)(x, y) == pytest.approx(value, rel=1e-14)


def test_glint_has_unit_mean_and_the_expected_std_over_positions_and_directions():
    rng = np.random.default_rng(2)
    x, y = rng.uniform(-1.0, 1.0, (2, 100_000))
    wi, wo = (v * np.sign(v[:, 2:]) / np.linalg.norm(v, axis=1, keepdims=True)    # upper hemisphere
              for v in rng.normal(size=(2, 100_000, 3)))
    values = GlintTexture(contrast=0.1, grain_m=5e-4, angle_rad=np.radians(2), seed=9)(x, y, wi, wo)
    assert values.mean() == pytest.approx(1.0, abs=1e-3)
    assert values.std() == pytest.approx(0.1 * (26 / 35) ** 2, rel=0.03)   # smoothstep blend over 4 axes
    np.testing.assert_allclose(GlintTexture(0.0, 5e-4, np.radians(2), 9)(x[:50], y[:50], wi[:50], wo[:50]), 1.0,
                               rtol=1e-15, atol=0)


def test_glint_roi_means_decorrelate_with_half_vector_separation():
    """ROI means of two views: ≈ the same draw below 0.2 pitch, independent beyond 2√2 pitches."""
    angle = np.radians(2)
    glint = GlintTexture(contrast=0.1, grain_m=5e-4, angle_rad=angle, seed=5)
    rng = np.random.default_rng(0)
    n = 500
    pixels = np.arange(10) * 2e-4
    x = (np.arange(n) * 0.05)[:, None, None] + pixels[None, :, None]   # ROIs 5 cm apart: independent
    y = pixels[None, None, :]
    h1 = rng.uniform(-0.3, 0.3, (n, 2))                                # random phases on the lattice
    psi = rng.uniform(0, 2 * np.pi, n)

    def roi_means(hxy):
        h = np.column_stack([hxy, np.sqrt(1 - (hxy ** 2).sum(axis=1))])[:, None, None, :]
        return glint(x, y, h, h).mean(axis=(1, 2))                      # ωi = ωo = h: retroreflection

    first = roi_means(h1)
    correlation = {sep: np.corrcoef(first, roi_means(h1 + sep * angle * np.column_stack(
        [np.cos(psi), np.sin(psi)])))[0, 1] for sep in (0.1, 0.2, 3.0, 5.0)}
    assert correlation[0.1] > 0.95 and correlation[0.2] > 0.9
    assert abs(correlation[3.0]) < 0.2 and abs(correlation[5.0]) < 0.2


def test_texture_is_seeded_continuous_and_path_independent():
    texture = ValueNoiseTexture(0.1, 1e-3, seed=3)
    x, y = np.meshgrid(np.linspace(-0.01, 0.01, 120), np.linspace(0.02, 0.03, 90))
    dense = texture(x, y)                                              # tabulated lattice block
    sparse = texture(x.ravel()[::997], y.ravel()[::997])               # per-point hashing
    np.testing.assert_allclose(sparse, dense.ravel()[::997], rtol=1e-12)
    np.testing.assert_allclose(dense, ValueNoiseTexture(0.1, 1e-3, seed=3)(x, y), rtol=1e-15, atol=0)
    assert not np.allclose(dense, ValueNoiseTexture(0.1, 1e-3, seed=4)(x, y))
    assert np.abs(texture(x + 1e-7, y) - dense).max() < 1e-3
    np.testing.assert_allclose(ValueNoiseTexture(0.0, 1e-3, 3)(x, y), 1.0, rtol=1e-15, atol=0)


# --- compiled paths against their numpy definitions ----------------------------------------

def test_lit_view_is_the_optics_modules_geometry():
    """camera.lit_view against rig.physics.optics' pixel_rays → intersect_sample_plane → in_beam, pixel by pixel."""
    for angles in [(60, 0, 34.8, 90), (80, 0, 10.7, 180), (5, 147, 31, 16), (37, 323, 78, 304)]:
        cam = make_camera(angles=angles)
        alpha, beta, a, b = np.radians(cam.world.motor_angles_deg())
        frame = sample_frame(alpha, beta)
        box = Window(400, 100, 600, 840)
        lit, xy, wo = lit_view(cam.optics, a, b, box, frame, 0.0375)
        origin, rays = pixel_rays(cam.optics, a, b, box)
        points = intersect_sample_plane(origin, rays, frame[:, 2])
        expected_lit = in_beam(points, 0.0375)
        assert expected_lit.any() and not expected_lit.all()
        np.testing.assert_array_equal(lit, expected_lit)
        # the same quantities by other roundings: a picometre is 2e-9 of a glint grain (0.5 mm)
        np.testing.assert_allclose(xy, points[expected_lit] @ frame[:, :2], rtol=0, atol=1e-12)
        np.testing.assert_allclose(wo, rays[expected_lit] @ -frame, rtol=0, atol=1e-12)
    cam = make_camera(angles=(30, 0, 20, 90))
    alpha, beta, a, b = np.radians(cam.world.motor_angles_deg())
    assert not lit_view(cam.optics, a, b, box, sample_frame(alpha, beta), -1.0)[0].any()   # negative radius


