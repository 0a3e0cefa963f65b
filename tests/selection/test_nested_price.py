"""The curvature Bayes factor between prismatic and revolute (docs/selection.md §2)."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.selection.nested_price import NestedPrice, curvature_estimate, log_bayes_factor, window_log_bayes_factor

PRICE = NestedPrice()


def _bent_line(rng, length_m, kappa, sigma=0.002, n=60):
    x = np.linspace(-length_m / 2, length_m / 2, n)
    return np.column_stack([x, 0.5 * kappa * x ** 2, np.zeros(n)]) + rng.normal(0, sigma, (n, 3))


def _arc(rng, radius_m, sweep_deg, sigma=0.002, n=60):
    t = np.radians(np.linspace(0.0, sweep_deg, n))
    return np.column_stack([radius_m * np.cos(t), radius_m * np.sin(t), np.zeros(n)]) + rng.normal(0, sigma, (n, 3))


def test_curvature_estimate_recovers_a_known_bend():
    rng = np.random.default_rng(0)
    kappa, sd, length = curvature_estimate(_bent_line(rng, 0.6, 0.5, sigma=0.001), 0.001)
    assert np.linalg.norm(kappa) == pytest.approx(0.5, abs=4 * sd + 0.02)
    assert length == pytest.approx(0.6, abs=0.01)


@pytest.mark.parametrize("kappa", [0.0, 0.3, 0.5])
def test_a_slide_bent_by_the_camera_prices_as_prismatic(kappa):
    # Curvatures up to ~1.7 σ_b (radius ≥ 2 m): the line is the simpler explanation.
    rng = np.random.default_rng(1)
    assert window_log_bayes_factor(_bent_line(rng, 0.6, kappa), 0.002, PRICE) < 0.0


@pytest.mark.parametrize("radius, sweep", [(0.3, 40.0), (0.3, 200.0), (0.6, 45.0), (0.9, 60.0)])
def test_a_hinge_prices_as_revolute(radius, sweep):
    rng = np.random.default_rng(2)
    assert window_log_bayes_factor(_arc(rng, radius, sweep), 0.002, PRICE) > np.log(9.0)  # p > 0.9


def test_outliers_do_not_make_a_line_curved():
    rng = np.random.default_rng(3)
    points = _bent_line(rng, 0.5, 0.0)
    points[[10, 30, 31]] += [0.0, 0.15, 0.05]
    assert window_log_bayes_factor(points, 0.002, PRICE) < 0.0


def test_no_evidence_either_way_on_a_tiny_window_and_bad_priors_are_refused():
    assert window_log_bayes_factor(np.zeros((4, 3)), 0.002, PRICE) == 0.0
    with pytest.raises(ValueError, match="radius_max_m: expected a finite number > 1.0, got 0.5"):
        NestedPrice(radius_min_m=1.0, radius_max_m=0.5)
    # Symmetric in the direction of the bend: only its size matters.
    assert log_bayes_factor([0.8, 0.0], 0.05, PRICE) == pytest.approx(log_bayes_factor([0.0, -0.8], 0.05, PRICE))
