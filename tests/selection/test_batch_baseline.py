"""The batch baseline: MLESAC fits of the three models chosen by BIC (docs/selection.md §3)."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.selection.batch import BatchSettings, batch_select, circle_through, distances


def test_circle_through_three_points():
    centre, normal, radius = circle_through(np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), np.array([-1.0, 0, 0]))
    assert np.allclose(centre, 0.0) and radius == pytest.approx(1.0) and abs(normal[2]) == pytest.approx(1.0)
    assert circle_through(np.zeros(3), np.ones(3), 2 * np.ones(3)) is None


def _with_outliers(rng, points, k=4):
    points = points + rng.normal(0, 0.002, points.shape)
    points[rng.choice(len(points), k, replace=False)] += rng.uniform(0.05, 0.2, (k, 3))
    return points


@pytest.mark.parametrize("seed", range(3))
def test_each_model_is_recognised_despite_outliers(seed):
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 1, 120)
    still = _with_outliers(rng, np.tile([0.3, -0.2, 1.0], (120, 1)))
    line = _with_outliers(rng, np.column_stack([0.5 * t, 0.2 * t, np.zeros_like(t)]))
    arc = _with_outliers(rng, np.column_stack([0.5 * np.cos(1.5 * t), 0.5 * np.sin(1.5 * t), np.zeros_like(t)]))
    settings = BatchSettings(spacing_m=0.0)
    assert batch_select(still, settings).model == "static"
    assert batch_select(line, settings).model == "prismatic"
    result = batch_select(arc, settings)
    assert result.model == "revolute" and result.structures["revolute"][2] == pytest.approx(0.5, abs=0.01)
    assert np.median(distances("revolute", arc, result.structures["revolute"])) < 0.005


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="finite"):
        batch_select(np.full((10, 3), np.nan), BatchSettings())
