"""The residual trends that screen for a second cause (cvmeasure.diagnose.residuals)."""

from __future__ import annotations

import numpy as np

from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose.residuals import residual_trends


def test_a_home_shift_walk_is_a_trend_though_no_index_trend_shows_it():
    # a drift whose lost steps shift home: bend k is moved by -d sum_{j<k} s_j (signed),
    # which walks about zero on a plan that alternates directions at random; no trend
    # along the bend index or its signed version follows it (before the `home_walk`
    # covariate the screen for a second cause missed it)
    rng = np.random.default_rng(3)
    n = 60
    s = rng.permutation(np.where(np.arange(n) % 2 == 0, 1.0, -1.0))
    cmd = s * rng.uniform(20.0, 120.0, n)
    walk = -(np.cumsum(s) - s)
    home_deg = 0.04 * walk
    noise = rng.normal(0.0, 0.02, (2, n))
    trials = TrialTable.from_arrays(cmd, cmd + home_deg + noise[0], cmd + home_deg + noise[1])
    residual = np.concatenate([home_deg + noise[0], home_deg + noise[1], np.full(n, np.nan)])
    trends = {t.covariate: t for t in residual_trends(trials, residual)}
    assert trends["home_walk"].p_value < 1e-10
    assert trends["home_walk"].suggests == ("drift",)
    assert trends["home_walk"].correlation > 0.9
    # the index trends do not see it (p > 1e-4, the screen's threshold)
    assert trends["bend_index"].p_value > 1e-4
    assert trends["signed_bend_index"].p_value > 1e-4
