"""Window evidence of the moving models (stslam.articulation.window_evidence, SPEC 4, 13, 18)."""

import numpy as np
import pytest

from stslam.articulation.window_evidence import (QUIET_WEIGHT, TURN_CAP, PairTurn, quiet_log_odds, rest_means,
                                                 revolute_log_odds, turn_log_odds)

SIGMA = 0.04  # the kitchen's sensor noise (SPEC 5.2)


def _door_window(rng, radius=0.45, opening=1.3, rest=20, swing=10, sigma=SIGMA):
    """A point on a door about the z axis: at rest closed, swinging open, at rest open (the kitchen's
    pattern of motion); positions with isotropic noise."""
    phi = np.concatenate([np.zeros(rest), np.linspace(0.0, opening, swing), np.full(rest, opening)])
    p = np.column_stack([radius * np.cos(phi), radius * np.sin(phi), np.full(phi.size, 1.0)])
    return p + rng.normal(0.0, sigma, p.shape)


def _drawer_window(rng, travel=0.4, rest=20, swing=10, sigma=SIGMA):
    s = np.concatenate([np.zeros(rest), np.linspace(0.0, travel, swing), np.full(rest, travel)])
    p = np.column_stack([np.full(s.size, 2.0), s, np.full(s.size, 0.8)])
    return p + rng.normal(0.0, sigma, p.shape)


def test_rest_means_keep_the_motion_and_average_the_rests():
    rng = np.random.default_rng(0)
    p = _drawer_window(rng, rest=30, swing=6, travel=1.0)
    means, variances = rest_means(p, np.full(len(p), SIGMA ** 2))
    # the two rests become one point each, of variance σ²/n (n ≈ 30 ± the swing points they absorb)
    assert 2 + 2 <= len(means) <= 2 + 6
    assert variances.min() < SIGMA ** 2 / 20
    np.testing.assert_allclose(means[0], [2.0, 0.0, 0.8], atol=4 * SIGMA / np.sqrt(20))


def test_a_door_favours_the_circle_and_a_drawer_does_not():
    # 20 noise draws each. A 0.45 m door opening 1.3 rad with ten points in its swing has a sagitta
    # of 8 cm (two σ): the circle wins clearly on nearly every draw. A line is the circle's limit, so
    # a drawer's evidence can only lean towards the line by the BIC's price of the circle: its median
    # is below 0 and almost no draw passes the revision margin of 3 (measured: 0.55 of the draws
    # below 0, median -0.3, one draw at 9.8).
    rng = np.random.default_rng(1)
    doors = np.array([revolute_log_odds(_door_window(rng), np.full(50, SIGMA ** 2)) for _ in range(20)])
    drawers = np.array([revolute_log_odds(_drawer_window(rng), np.full(50, SIGMA ** 2)) for _ in range(20)])
    assert np.mean(doors > 0) >= 0.85 and np.median(doors) > 5.0
    assert np.median(drawers) < 0.0 and np.mean(drawers < 3.0) >= 0.9
    # with less noise a door is overwhelming, a drawer still only a lean
    assert revolute_log_odds(_door_window(rng, sigma=0.005), np.full(50, 0.005 ** 2)) > 20
    assert revolute_log_odds(_drawer_window(rng, sigma=0.005), np.full(50, 0.005 ** 2)) < 3.0  # never a revision


def test_a_short_window_says_nothing():
    assert revolute_log_odds(np.zeros((3, 3)) + np.arange(3)[:, None], np.full(3, SIGMA ** 2)) == 0.0


def _pair(points_a, points_b):
    n = len(points_a)
    cov = np.repeat((SIGMA ** 2 * np.eye(3))[None], n, axis=0)
    return points_a, points_b, cov, cov


@pytest.mark.parametrize("seed", range(5))
def test_a_pair_across_a_turning_door_turned_and_a_sliding_pair_did_not(seed):
    rng = np.random.default_rng(seed)
    # two points of one door, 0.25 m and 0.45 m from the hinge: their difference turns by 1.3 rad
    edge = _door_window(np.random.default_rng(100 + seed), radius=0.45, sigma=0.0)
    inner = edge * np.array([0.25 / 0.45, 0.25 / 0.45, 1.0])
    noisy = [p + rng.normal(0.0, SIGMA, p.shape) for p in (edge, inner)]
    assert turn_log_odds(*_pair(*noisy)) == TURN_CAP
    # two corners of a drawer 0.4 m apart: the difference stays put, a weak vote for a slide
    front = _drawer_window(rng)
    corner = front + np.array([0.0, 0.0, 0.4]) + rng.normal(0.0, SIGMA, front.shape)
    assert turn_log_odds(*_pair(front, corner)) == -QUIET_WEIGHT
    # two points of a door along its hinge move alike too: a close pair says nothing
    above = edge + np.array([0.0, 0.0, 0.1]) + rng.normal(0.0, SIGMA, edge.shape)
    assert turn_log_odds(*_pair(edge + rng.normal(0.0, SIGMA, edge.shape), above)) == 0.0


def test_quiet_pairs_count_only_along_two_directions():
    up, across, oblique = np.array([0.0, 0.0, 0.3]), np.array([0.4, 0.0, 0.0]), np.array([0.05, 0.0, -0.2])
    quiet = [PairTurn(-QUIET_WEIGHT, d) for d in (up, across)]
    assert quiet_log_odds(quiet) == -2 * QUIET_WEIGHT  # no hinge lies along both
    # the kitchen's wall cabinet door: its pairs are 0-14° from its vertical hinge, a turn leaves them quiet
    assert quiet_log_odds([PairTurn(-QUIET_WEIGHT, d) for d in (up, -up, oblique)]) == 0.0
    assert quiet_log_odds([PairTurn(-QUIET_WEIGHT, across)]) == 0.0  # one pair alone: it may lie along the hinge
    assert quiet_log_odds([]) == 0.0


def _rest_means_on_arrays(points, variances, spread=3.0):
    """rest_means as first written, on numpy arrays (the reference for the scalar loop)."""
    means, weights = [], []
    total, weight = np.zeros(3), 0.0
    for p, v in zip(points, variances):
        if weight > 0.0:
            mean = total / weight
            if np.sum((p - mean) ** 2) > spread ** 2 * v:
                means.append(mean)
                weights.append(weight)
                total, weight = np.zeros(3), 0.0
        total, weight = total + p / v, weight + 1.0 / v
    means.append(total / weight)
    weights.append(weight)
    return np.array(means), 1.0 / np.array(weights)


def test_rest_means_are_those_of_the_array_loop():
    # Same IEEE operations in the same order on Python floats: equal to the last bit (no tolerance).
    rng = np.random.default_rng(4)
    for _ in range(50):
        points = _door_window(rng, rest=int(rng.integers(0, 25)), swing=int(rng.integers(1, 15)),
                              sigma=rng.uniform(0.005, 0.1))
        variances = rng.uniform(1e-4, 1e-2, len(points))
        for got, want in zip(rest_means(points, variances), _rest_means_on_arrays(points, variances)):
            np.testing.assert_array_equal(got, want)


def _cabinet_pair(rng, sigma=SIGMA):
    """Two points of the kitchen's wall cabinet door (conf/world/kitchen.yaml), 0.35 m and 0.30 m from its
    vertical hinge and 0.2 m apart along it, at the frames a kitchen run sees it (seed 1001: 0–17, 101–128,
    212–238): closed and beginning to open, open by 0.91 rad and closing, closed and opening by 0.78 rad."""
    phi = np.concatenate([np.zeros(12), np.linspace(0.0, 0.72, 6), np.full(20, 0.91), np.linspace(0.91, 0.0, 8),
                          np.zeros(10), np.linspace(0.0, 0.78, 10), np.full(7, 0.78)])
    def point(radius, height):
        return np.column_stack([-radius * np.cos(phi), -radius * np.sin(phi), np.full(phi.size, height)])
    noise = rng.normal(0.0, sigma, (2, phi.size, 3))
    return point(0.35, 1.8) + noise[0], point(0.30, 1.6) + noise[1]


def test_a_pair_nearly_along_the_hinge_turned_by_how_it_moved_with_its_door():
    # The pair's difference is 5 cm across the hinge: a 0.91 rad turn moves it by 4.4 cm against a
    # difference noise of 5.7 cm a frame. Spread over all 73 frames (216 dof), the χ² about the mean
    # alone (the test before the score, at 1e-3) found it on none of these 40 draws; with the score along
    # the door's own motion (3 dof) the turn is found on 9 (measured). The signal is weak at this noise:
    # the bound asks for a clear gain over none, not for most draws.
    from scipy.special import chdtrc

    from stslam.articulation.window_kernels import turn_statistic
    rng = np.random.default_rng(7)
    before = found = 0
    for _ in range(40):
        pair = _pair(*_cabinet_pair(rng))
        before += chdtrc(3 * (len(pair[0]) - 1), turn_statistic(*pair)[1]) < 1e-3
        found += turn_log_odds(*pair) == TURN_CAP
    assert before == 0 and found >= 6


def test_the_turn_score_is_chi2_with_3_dof_on_a_slide():
    # Two corners of a sliding drawer: d_t is constant, so the score is χ²₃ whatever the motion. Over 400
    # draws its p-values are uniform: about half below 0.5, about 1% below 0.01 (binomial bounds at ±4σ).
    from scipy.special import chdtrc

    from stslam.articulation.window_kernels import turn_score, turn_statistic
    rng = np.random.default_rng(11)
    p = []
    for _ in range(400):
        clean = _drawer_window(rng, sigma=0.0)
        a, b, ca, cb = _pair(clean + rng.normal(0.0, SIGMA, clean.shape),
                             clean + np.array([0.3, 0.0, 0.2]) + rng.normal(0.0, SIGMA, clean.shape))
        ok, _, mean = turn_statistic(a, b, ca, cb)
        p.append(chdtrc(3, turn_score(a, b, ca, cb, mean, 5)))
    p = np.array(p)
    assert abs(np.mean(p < 0.5) - 0.5) < 4 * np.sqrt(0.25 / 400)
    assert np.sum(p < 0.01) <= 4 + 4 * np.sqrt(4)
