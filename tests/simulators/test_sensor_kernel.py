"""The compiled sensor read-out (rig.simulators._sensor_kernel) against the distributions it must draw.

Statistical checks are sized for false failures below ~1e-6 on any seed: moments within 5 standard errors
(two-sided 5.7e-7), counts and histograms by exact binomial / chi-square / Kolmogorov–Smirnov tests at
p > 1e-6. The seeds are fixed, so the tests are also reproducible. No timing here (benchmarks/hot_paths.py).
"""

import numpy as np
import pytest
from scipy import special, stats

from rig.config.rigfile import CameraConfig, SimulationConfig
from rig.core.values import Window
from rig.simulators import sensor
from rig.simulators.sensor import NORMAL_MAX_SKEWNESS, SATURATION_GUARD, SensorModel, convert_nonlinear

kernel = sensor._sensor_kernel
pytestmark = pytest.mark.skipif(kernel is None, reason="rig.simulators._sensor_kernel was not built")

P_MIN = 1e-6
K_DEFAULT = CameraConfig().gain_dn_per_e          # 4031/18000 DN/e⁻
SHAPE = (512, 512)


def read(mean_e, shape=SHAPE, read_noise_e=8.0, seed=1, gain=K_DEFAULT, black=64.0, bits=12, full_well=18000.0,
         nonlinearity=0.0, response=None, dark=None, rows=None):
    """A frame from the kernel with response 1 and no dark current unless given: the mean charge is mean_e (a
    float, or an array as the luminance with responsivity·t = 1); `rows` splits it into bands."""
    out = np.empty(shape, np.uint16)
    response = np.ones(shape, np.float32) if response is None else response
    dark = np.zeros(shape, np.float32) if dark is None else dark
    edges = rows or [0, shape[0]]
    for y0, y1 in zip(edges[:-1], edges[1:]):
        kernel.read_rows(out, response, dark, mean_e, 1.0, 1.0, read_noise_e, full_well, SATURATION_GUARD,
                         NORMAL_MAX_SKEWNESS, nonlinearity, gain, black, bits, seed, y0, y1)
    return out


def exact_regime(mean_e, read_noise_e):
    """Whether sensor.electrons draws exact Poisson + read noise (else the normal)."""
    return mean_e ** 2 > NORMAL_MAX_SKEWNESS ** 2 * (mean_e + read_noise_e ** 2) ** 3


def chi_square_p(observed, expected_p, min_expected=20.0):
    """p-value of a chi-square test of counts against probabilities, adjacent bins pooled to ≥ min_expected."""
    observed, expected = np.asarray(observed, float), np.asarray(expected_p, float) * np.sum(observed)
    pooled: list[list[float]] = [[0.0, 0.0]]
    for o, e in zip(observed, expected):
        if pooled[-1][1] >= min_expected:
            pooled.append([0.0, 0.0])
        pooled[-1][0] += o
        pooled[-1][1] += e
    if len(pooled) > 1 and pooled[-1][1] < min_expected:       # a short last group joins the one before
        o, e = pooled.pop()
        pooled[-1][0] += o
        pooled[-1][1] += e
    obs, exp = np.array(pooled).T
    return stats.chisquare(obs, exp * obs.sum() / exp.sum()).pvalue      # (the far tails' last 1e-12)


def dn_pmf(mean_e, read_noise_e, gain=K_DEFAULT, black=64.0, bits=12):
    """Exact pmf of DN = clip(rint(black + K·e)) over 0 … 2^bits − 1, e drawn as sensor.electrons draws it."""
    top = 2 ** bits - 1
    edges = (np.arange(0.5, top) - black) / gain          # charge boundaries between DN n and n + 1
    if exact_regime(mean_e, read_noise_e):
        k = np.arange(0, int(mean_e + 15 * np.sqrt(mean_e) + 30))
        pk = stats.poisson.pmf(k, mean_e)
        if read_noise_e == 0:
            cdf = np.array([pk[k <= e].sum() for e in edges])
        else:
            cdf = (pk[None, :] * special.ndtr((edges[:, None] - k[None, :]) / read_noise_e)).sum(axis=1)
    else:
        cdf = special.ndtr((edges - mean_e) / np.sqrt(mean_e + read_noise_e ** 2))
    return np.diff(np.concatenate([[0.0], cdf, [1.0]]))


# --- the generators ----------------------------------------------------------------------------

def test_ziggurat_normals_have_the_standard_normal_distribution():
    n = 10_000_000
    z = np.empty(n)
    kernel.standard_normal(12345, z)
    se = 1 / np.sqrt(n)
    assert abs(z.mean()) < 5 * se
    assert abs(z.var() - 1) < 5 * np.sqrt(2) * se
    assert abs(stats.skew(z)) < 5 * np.sqrt(6) * se
    assert abs(stats.kurtosis(z)) < 5 * np.sqrt(24) * se
    for k in (3.0, 3.6541528853610088, 4.0, 4.5):       # ±r: the base strip's edge, beyond it the tail
        count = int(np.count_nonzero(np.abs(z) > k))
        assert stats.binomtest(count, n, 2 * special.ndtr(-k)).pvalue > P_MIN, k
    assert stats.kstest(z[:1_000_000], "norm").pvalue > P_MIN
    # 2000 equiprobable bins: any layer's rectangle or wedge of the wrong size shows here
    u = special.ndtr(z)
    counts = np.bincount(np.minimum((u * 2000).astype(int), 1999), minlength=2000)
    assert chi_square_p(counts, np.full(2000, 1 / 2000)) > P_MIN
    positive = int(np.count_nonzero(z > 0))
    assert stats.binomtest(positive, n, 0.5).pvalue > P_MIN


def test_generators_are_deterministic_per_seed():
    a, b, c = np.empty(1000), np.empty(1000), np.empty(1000)
    kernel.standard_normal(7, a)
    kernel.standard_normal(7, b)
    kernel.standard_normal(8, c)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    kernel.poisson(7, 37.0, a)
    kernel.poisson(7, 37.0, b)
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("mean", [0.5, 3.0, 9.9, 10.0, 14.0, 37.0, 500.0, 2400.0, 1e5])
def test_poisson_deviates_have_the_poisson_distribution(mean):
    """Inversion below 10, Ahrens & Dieter's PD from 10 (its rare steps Q, E and H run most near 10)."""
    n = 2_000_000 if mean < 50 else 1_000_000
    k = np.empty(n)
    kernel.poisson(2024 + int(mean), mean, k)
    assert np.all(k >= 0) and np.all(k == np.floor(k))
    assert abs(k.mean() - mean) < 5 * np.sqrt(mean / n)
    assert abs(k.var() - mean) < 5 * np.sqrt((mean + 2 * mean ** 2) / n)
    counts = np.bincount(k.astype(np.int64))
    support = np.arange(counts.size)
    pmf = stats.poisson.pmf(support, mean)
    pmf[-1] += stats.poisson.sf(support[-1], mean)
    pmf[0] += stats.poisson.cdf(-1, mean)
    assert chi_square_p(counts, pmf) > P_MIN


def test_poisson_of_zero_is_zero_and_bad_means_are_refused():
    k = np.ones(100)
    kernel.poisson(1, 0.0, k)
    assert not k.any()
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="mean"):
            kernel.poisson(1, bad, k)


# --- the frame ---------------------------------------------------------------------------------

@pytest.mark.parametrize("mean_e, read_noise_e", [
    (0.0, 8.0),          # a dark frame: the normal
    (3.0, 0.0),          # exact Poisson by inversion, no read noise: DN only where K·k rounds
    (50.0, 8.0),         # exact Poisson (PD) + read noise
    (1000.0, 8.0),       # still exact: skewness 0.029
    (5000.0, 8.0),       # the normal
    (12000.0, 30.0),     # the normal, bright
], ids=["dark", "poisson-3", "poisson-50", "poisson-1000", "normal-5000", "normal-12000"])
def test_frame_follows_its_exact_distribution_and_the_photon_transfer_relation(mean_e, read_noise_e):
    frame = read(mean_e, read_noise_e=read_noise_e, seed=int(mean_e) + 3)
    counts = np.bincount(frame.ravel(), minlength=4096)
    pmf = dn_pmf(mean_e, read_noise_e)
    assert chi_square_p(counts, pmf) > P_MIN
    y = frame.astype(float)
    n = y.size
    levels = np.arange(4096)
    mu, var = pmf @ levels, pmf @ (levels - pmf @ levels) ** 2
    fourth = pmf @ (levels - mu) ** 4
    assert abs(y.mean() - mu) < 5 * np.sqrt(var / n)
    assert abs(y.var() - var) < 5 * np.sqrt((fourth - var ** 2) / n)
    # EMVA 1288: σy² = K²σd² + σq² + K(μy − μy,dark), where the quantisation's 1/12 holds (σy ≳ 1 DN)
    if var > 1:
        dark = read(0.0, read_noise_e=read_noise_e, seed=99).astype(float)
        emva = K_DEFAULT ** 2 * read_noise_e ** 2 + 1 / 12 + K_DEFAULT * (y.mean() - dark.mean())
        assert y.var() == pytest.approx(emva, rel=0.02)


def test_regimes_of_the_frame_cases():
    assert not exact_regime(0.0, 8.0) and not exact_regime(5000.0, 8.0) and not exact_regime(12000.0, 30.0)
    assert exact_regime(3.0, 0.0) and exact_regime(50.0, 8.0) and exact_regime(1000.0, 8.0)


@pytest.mark.parametrize("mean_e", [18000.0, 20000.0, 1e6, 1e30, float("inf")])
def test_saturated_pixels_read_exactly_the_full_well(mean_e):
    """Read noise is added before the full-well clip; the full well is 1864 DN here, under the ADC's 4095.
    20000 e⁻ is 14σ above it."""
    frame = read(mean_e, shape=(64, 64), read_noise_e=8.0, gain=0.1)
    full_well_dn = round(64 + 0.1 * 18000)
    if mean_e == 18000.0:                                      # half the pixels fall short
        assert frame.max() == full_well_dn and 0.3 < np.mean(frame == full_well_dn) < 0.7
    else:
        assert (frame == full_well_dn).all()


def test_adc_clips_at_zero_and_at_its_top():
    low = read(0.0, read_noise_e=8.0, gain=1.0, black=0.0)               # half the charge is negative
    assert low.min() == 0 and low.max() < 60
    assert np.mean(low == 0) == pytest.approx(special.ndtr(0.5 / 8.0), abs=0.005)
    high = read(5000.0, shape=(64, 64), bits=8, gain=1.0, black=10.0)
    assert (high == 255).all()
    top16 = read(17000.0, shape=(64, 64), bits=16, gain=4.0, black=10.0)  # 68010 DN > 65535: no wrap-around
    assert (top16 == 65535).all()


def test_nonlinearity_bends_the_mean_as_convert_nonlinear():
    mean_e, beta = 9000.0, 0.05
    y = read(mean_e, read_noise_e=8.0, nonlinearity=beta).astype(float)
    expected = 64 + K_DEFAULT * convert_nonlinear(np.float64(mean_e), beta, 18000.0)
    # E[e(1 − β(1 − e/FW))] exceeds the bent mean by β·var/FW ≈ 0.025 e⁻: far below the 5 SE tolerance
    assert abs(y.mean() - expected) < 5 * np.sqrt(y.var() / y.size) + K_DEFAULT * beta * mean_e / 18000


# --- determinism, bands, windows ---------------------------------------------------------------

def test_a_frame_depends_on_its_seed_only_not_on_the_bands():
    lum = np.random.default_rng(0).uniform(0, 3000, SHAPE)     # both regimes in one frame
    whole = read(lum, seed=5)
    np.testing.assert_array_equal(whole, read(lum, seed=5))
    np.testing.assert_array_equal(whole, read(lum, seed=5, rows=[0, 1, 7, 256, 300, 511, 512]))
    np.testing.assert_array_equal(whole, read(lum, seed=5, rows=list(range(0, 513))))
    assert np.mean(whole != read(lum, seed=6)) > 0.5


def test_model_read_does_not_depend_on_the_threads(monkeypatch):
    model = SensorModel.from_config(CameraConfig(), SimulationConfig(), np.random.default_rng(0))
    window = Window(0, 0, 1390, 1040)                          # above rig.core.bands.PARALLEL_MIN_PX
    threaded = model.read(np.random.default_rng(4), 30.0, 0.01, window)
    monkeypatch.setattr(sensor, "run_in_bands", lambda rows, height, width: rows(0, height))
    np.testing.assert_array_equal(threaded, model.read(np.random.default_rng(4), 30.0, 0.01, window))
    rng = np.random.default_rng(4)
    assert not np.array_equal(model.read(rng, 30.0, 0.01, window), model.read(rng, 30.0, 0.01, window))


def test_windows_and_strided_views_read_like_contiguous_copies():
    rng = np.random.default_rng(3)
    response = rng.uniform(0.9, 1.1, (300, 400)).astype(np.float32)
    dark = rng.uniform(0, 50, (300, 400)).astype(np.float32)
    lum = rng.uniform(0, 2000, (300, 400))
    for view in (np.s_[17:217, 33:333], np.s_[::2, 1::3], np.s_[::-1, 5:105]):
        args = response[view], dark[view], lum[view]
        frame = read(args[2], shape=args[0].shape, response=args[0], dark=args[1], seed=11)
        copies = [np.ascontiguousarray(a) for a in args]
        np.testing.assert_array_equal(frame, read(copies[2], shape=args[0].shape, response=copies[0],
                                                  dark=copies[1], seed=11))
    # float32 luminance is read as numpy's dtype=float32 cast of float64 reads it
    np.testing.assert_array_equal(read(lum, shape=lum.shape, seed=2),
                                  read(lum.astype(np.float32), shape=lum.shape, seed=2))
    np.testing.assert_array_equal(read(np.full(SHAPE, 700.0), seed=2), read(700.0, seed=2))


# --- compiled and numpy paths ------------------------------------------------------------------

@pytest.mark.parametrize("mean_e", [0.0, 50.0, 1000.0, 5000.0])
@pytest.mark.parametrize("nonlinearity_rel", [0.0, 0.05])
def test_compiled_and_numpy_reads_agree_in_distribution(monkeypatch, mean_e, nonlinearity_rel):
    """Mean and variance of a 400×400 window (the same cos⁴-shaded mean image on both paths), within 5 standard
    errors of their difference."""
    cam = CameraConfig()
    model = SensorModel.from_config(cam, SimulationConfig(nonlinearity_rel=nonlinearity_rel),
                                    np.random.default_rng(0))
    window, t = Window.centred(1390, 1040, 400, 400), 0.02
    lum = mean_e / (cam.responsivity_e_per_cd_m2_s * t)
    compiled = model.read(np.random.default_rng(1), lum, t, window).astype(float)
    monkeypatch.setattr(sensor, "_sensor_kernel", None)
    numpy_path = model.read(np.random.default_rng(1), lum, t, window).astype(float)
    n = compiled.size
    assert abs(compiled.mean() - numpy_path.mean()) < 5 * np.sqrt(2 * compiled.var() / n)
    fourth = np.mean((compiled - compiled.mean()) ** 4)
    assert abs(compiled.var() - numpy_path.var()) < 5 * np.sqrt(2 * (fourth - compiled.var() ** 2) / n)


# --- errors --------------------------------------------------------------------------------------

def test_bad_arguments_raise_clear_errors():
    ok = dict(shape=(4, 5))
    with pytest.raises(TypeError, match="response"):
        read(1.0, response=np.ones((4, 5)), **ok)                              # float64
    with pytest.raises(ValueError, match="dark_e_s"):
        read(1.0, dark=np.zeros((5, 4), np.float32), **ok)
    with pytest.raises(TypeError, match="luminance"):
        read(np.ones((4, 5), np.int64), **ok)
    with pytest.raises(ValueError, match="luminance"):
        read(np.ones(5), **ok)
    out = np.empty((4, 5), np.float32)
    args = (np.ones((4, 5), np.float32), np.zeros((4, 5), np.float32), 1.0, 1.0, 1.0, 8.0, 18000.0, 2.0, 0.02,
            0.0, 0.2, 64.0, 12, 1)
    with pytest.raises(TypeError, match="out"):
        kernel.read_rows(out, *args, 0, 4)
    with pytest.raises(ValueError, match="out"):
        kernel.read_rows(np.empty((4, 10), np.uint16)[:, ::2], *args, 0, 4)    # not C-contiguous
    readonly = np.empty((4, 5), np.uint16)
    readonly.flags.writeable = False
    with pytest.raises(ValueError, match="out"):
        kernel.read_rows(readonly, *args, 0, 4)
    with pytest.raises(ValueError, match="rows"):
        kernel.read_rows(np.empty((4, 5), np.uint16), *args, 0, 5)
    with pytest.raises(ValueError, match="not a number"):
        read(np.full((4, 5), np.nan), **ok)
    with pytest.raises(ValueError, match="negative"):
        read(-1e4, **ok)
    model = SensorModel.from_config(CameraConfig(), SimulationConfig(), np.random.default_rng(0))
    with pytest.raises(ValueError, match="not a number"):
        model.read(np.random.default_rng(0), float("nan"), 0.01, Window(0, 0, 8, 8))
