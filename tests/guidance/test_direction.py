"""The guiding direction estimator (Algorithm 1 of seed 004) against the paper's behaviour."""

import math

import numpy as np
import pytest

from guidance import DirectionEstimatorSettings, GuidingDirectionEstimator
from guidance.direction import systematic_resample, wrap_angle


def _measurements(true_bearings, seed, noise_deg=8.0, reflection_rate=0.1):
    """Noisy bearings with momentary reflections from random directions."""
    rng = np.random.default_rng(seed)
    z = np.asarray(true_bearings) + rng.normal(0.0, math.radians(noise_deg), len(true_bearings))
    reflected = rng.random(len(true_bearings)) < reflection_rate
    z[reflected] = rng.uniform(-math.pi, math.pi, int(reflected.sum()))
    return z


def _errors_deg(estimator, truth, measured):
    pairs = zip(measured, truth, strict=True)
    return np.array([abs(math.degrees(wrap_angle(estimator.update(z) - t))) for z, t in pairs])


@pytest.mark.parametrize("true_deg", [40.0, 179.0, -100.0])
def test_converges_to_the_true_bearing_under_noise_and_reflections(true_deg):
    truth = np.full(200, math.radians(true_deg))
    estimator = GuidingDirectionEstimator(rng=np.random.default_rng(3))
    errors = _errors_deg(estimator, truth, _measurements(truth, seed=4))
    # The raw readings are off by 8 deg (1 sigma) and one in ten points anywhere; only two
    # reflections in a row may swing the estimate, for a step.
    assert errors[50:].mean() < 4.0
    assert np.mean(errors[50:] > 15.0) <= 0.02
    assert estimator.concentration > 0.8


def _steps_to_recover(dispersion, seed):
    truth = np.r_[np.full(100, math.radians(30.0)), np.full(200, math.radians(210.0))]
    settings = DirectionEstimatorSettings(dispersion_fraction=dispersion)
    estimator = GuidingDirectionEstimator(settings, np.random.default_rng(seed))
    errors = _errors_deg(estimator, truth, _measurements(truth, seed=seed + 100))
    after = errors[100:]
    settled = np.flatnonzero(after < 10.0)
    # First step from which the error stays under 10 deg for 20 steps.
    for k in settled:
        if (after[k : k + 20] < 10.0).all():
            return int(k)
    return len(after)


def test_dispersion_recovers_from_a_180_degree_jump_faster_than_a_plain_filter():
    with_dispersion = [_steps_to_recover(0.10, seed) for seed in range(4)]
    without = [_steps_to_recover(0.0, seed) for seed in range(4)]
    # Figure 3 of the paper: dispersion settles about twice as fast; here the plain filter
    # has to random-walk its collapsed particles half way round the circle.
    assert max(with_dispersion) <= 20
    assert np.mean(without) >= 2 * np.mean(with_dispersion)


def test_no_measurement_no_estimate_and_bad_readings_change_nothing():
    estimator = GuidingDirectionEstimator(rng=np.random.default_rng(0))
    assert estimator.bearing is None
    assert estimator.update(None) is None
    assert estimator.update(float("nan")) is None
    assert estimator.concentration < 0.01  # evenly spread: no evidence of any direction
    first = estimator.update(1.0)
    before = estimator.particles.copy()
    assert estimator.update(float("inf")) == first
    np.testing.assert_array_equal(estimator.particles, before)


def test_alternating_opposite_readings_never_produce_nan():
    estimator = GuidingDirectionEstimator(
        DirectionEstimatorSettings(measurement_noise=math.radians(0.5), outlier_probability=0.0),
        np.random.default_rng(1),
    )
    for k in range(300):
        bearing = estimator.update(0.0 if k % 2 else math.pi)
        assert math.isfinite(bearing)
        assert np.isfinite(estimator.weights).all()
        assert estimator.weights.sum() == pytest.approx(1.0)


def test_resamples_only_when_the_effective_sample_size_drops_below_the_threshold():
    estimator = GuidingDirectionEstimator(rng=np.random.default_rng(5))
    for _ in range(10):
        before = estimator.resamplings
        estimator.update(0.5)
        if estimator.resamplings > before:
            # Resampled: weights reset to 1/N, 10 % dispersed over the circle.
            assert estimator.effective_sample_size == pytest.approx(500.0)
        else:
            assert estimator.effective_sample_size >= 250.0
    assert estimator.resamplings >= 2
    # Once converged, the particles far from the bearing are the dispersed ones.
    far = np.abs(wrap_angle(estimator.particles - 0.5)) > math.radians(60)
    assert 0.05 * 500 <= far.sum() <= 0.12 * 500
    never = GuidingDirectionEstimator(
        DirectionEstimatorSettings(resample_threshold=1e-9), np.random.default_rng(5)
    )
    for _ in range(20):
        never.update(0.5)
    assert never.resamplings == 0


def test_systematic_resampling_keeps_each_particle_within_one_copy_of_its_share():
    rng = np.random.default_rng(7)
    weights = rng.random(1000) ** 4
    weights /= weights.sum()
    counts = np.bincount(systematic_resample(weights, rng), minlength=1000)
    assert counts.sum() == 1000
    assert (np.abs(counts - 1000 * weights) < 1.0 + 1e-9).all()


def test_same_seed_same_estimates():
    z = _measurements(np.full(50, 1.0), seed=9)
    runs = []
    for _ in range(2):
        estimator = GuidingDirectionEstimator(rng=np.random.default_rng(11))
        runs.append([estimator.update(v) for v in z])
    assert runs[0] == runs[1]


@pytest.mark.parametrize(
    "kwargs",
    [
        {"n_particles": 1},
        {"process_noise": 0.0},
        {"measurement_noise": float("nan")},
        {"dispersion_fraction": 1.0},
        {"resample_threshold": 600.0},
        {"outlier_probability": -0.1},
    ],
)
def test_settings_refuse_values_the_filter_cannot_use(kwargs):
    with pytest.raises(ValueError):
        DirectionEstimatorSettings(**kwargs)


def test_a_generator_is_required():
    with pytest.raises(ValueError, match="Generator"):
        GuidingDirectionEstimator()


def test_guidance_is_a_leaf_package():
    import ast
    import pathlib

    import guidance

    ours = {"autonomy", "behaviors", "lsm", "lsd", "sitl"}
    for path in pathlib.Path(guidance.__file__).parent.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or ""]
            else:
                continue
            assert not {n.split(".")[0] for n in names} & ours, path.name


def test_the_detector_returns_the_middle_of_the_lit_sectors():
    from guidance.detector import ring_bearing

    assert ring_bearing(0) is None
    assert ring_bearing(0xFFF) is None
    assert ring_bearing(1 << 3) == pytest.approx(math.radians(90))
    # Neighbours lit at range, across the nose: 330, 0, 30 deg -> 0.
    assert ring_bearing((1 << 11) | 1 | (1 << 1)) == pytest.approx(0.0)
    assert ring_bearing((1 << 4) | (1 << 5)) == pytest.approx(math.radians(135))
    # A reflection two sensors away widens the arc (the paper adds the ranges up).
    assert ring_bearing((1 << 6) | (1 << 8)) == pytest.approx(math.radians(210))
    assert ring_bearing(1 << 12) is None  # the downward sensor is not on the ring
