"""The NEES band for autocorrelated frames (SPEC 6.4): τ estimates and coverage on an exactly consistent filter."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.slam.consistency import autocorrelation_time, nees_band, nees_band_correlated

N_RUNS, N_STEPS = 50, 108  # dynamic_slam's default: 50 seeds, frames 2…109


def _ar1(rng, n_runs, n_steps, phi):
    """Stationary AR(1) runs with unit variance: τ = (1 + φ)/(1 − φ)."""
    x = np.empty((n_runs, n_steps))
    x[:, 0] = rng.standard_normal(n_runs)
    for k in range(1, n_steps):
        x[:, k] = phi * x[:, k - 1] + np.sqrt(1 - phi**2) * rng.standard_normal(n_runs)
    return x


def _kalman_nees(rng, n_runs, n_steps, q):
    """NEES of an exact Kalman filter: three independent random walks (process variance q,
    prior and measurement variance 1), so each frame's NEES is exactly χ²(3); small q makes
    the errors persist over many frames, as a SLAM map error does."""
    x = rng.standard_normal((n_runs, 3))
    estimate, P = np.zeros((n_runs, 3)), 1.0
    out = np.empty((n_runs, n_steps))
    for k in range(n_steps):
        x = x + np.sqrt(q) * rng.standard_normal(x.shape)
        P = P + q
        gain = P / (P + 1.0)
        estimate = estimate + gain * (x + rng.standard_normal(x.shape) - estimate)
        P = (1.0 - gain) * P
        out[:, k] = np.sum((x - estimate) ** 2, axis=1) / P
    return out


def test_autocorrelation_time_of_independent_and_ar1_series():
    rng = np.random.default_rng(1)
    # Independent frames: τ = 1; Geyer's sum adds positive noise pairs, ~+0.1 at this size.
    assert 1.0 <= autocorrelation_time(rng.chisquare(3, (N_RUNS, N_STEPS))) < 1.25
    # AR(1), φ = 0.8: τ = 9. 400 runs of 108 steps estimate it within ~10% (batch-means SE);
    # 25% leaves margin for the estimator's bias at a lag window of ~20 steps out of 108.
    assert autocorrelation_time(_ar1(rng, 400, N_STEPS, 0.8)) == pytest.approx(9.0, rel=0.25)


def test_correlated_band_reduces_to_the_independent_band():
    rng = np.random.default_rng(2)
    low, high, tau = nees_band_correlated(rng.chisquare(3, (N_RUNS, N_STEPS)))
    naive = nees_band(N_STEPS, 3, N_RUNS)
    # τ ≈ 1.1 widens the band by √τ ≈ 5%: the two agree to a few thousandths.
    assert low == pytest.approx(naive[0], abs=0.01) and high == pytest.approx(naive[1], abs=0.01)


@pytest.mark.parametrize("q, min_tau", [(0.003, 10.0), (0.0003, 30.0)], ids=["tau~18", "tau~47"])
def test_correlated_band_covers_a_consistent_filter_95_percent_of_the_time(q, min_tau):
    """Over 200 batches of 50 runs, an exactly consistent filter's mean NEES falls inside the
    correlated band in ~95% of batches; the band that treats frames as independent misses it
    most of the time. Binomial SE of a 95% coverage over 200 batches: 1.5%; [0.90, 0.99] is
    about ±3 SE. τ ≈ 47 is where dynamic_slam's A-SLAM sits (square_centred)."""
    rng = np.random.default_rng(3)
    naive = nees_band(N_STEPS, 3, N_RUNS)
    inside, inside_naive, taus = 0, 0, []
    for _ in range(200):
        nees = _kalman_nees(rng, N_RUNS, N_STEPS, q)
        low, high, tau = nees_band_correlated(nees)
        mean = nees.mean()
        inside += low <= mean <= high
        inside_naive += naive[0] <= mean <= naive[1]
        taus.append(tau)
    assert 0.90 <= inside / 200 <= 0.99
    assert inside_naive / 200 < 0.6
    assert np.median(taus) > min_tau  # the errors do persist: this is the regime the band is for


def test_band_width_does_not_follow_the_level():
    """A filter overconfident by a constant factor gets the same τ, so the same band, and fails it."""
    rng = np.random.default_rng(4)
    nees = _kalman_nees(rng, N_RUNS, N_STEPS, q=0.003)
    low, high, tau = nees_band_correlated(nees)
    low2, high2, tau2 = nees_band_correlated(1.5 * nees)
    assert tau2 == pytest.approx(tau, rel=1e-12) and (low2, high2) == pytest.approx((low, high), rel=1e-12)
    assert not low2 <= 1.5 * nees.mean() <= high2


def test_autocorrelation_time_rejects_bad_input():
    with pytest.raises(ValueError, match="series"):
        autocorrelation_time(np.ones(5))
    with pytest.raises(ValueError, match="series"):
        autocorrelation_time([[1.0, np.nan, 2.0]])
