"""The numpy peak search against scipy.signal.find_peaks, peak for peak."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import find_peaks as scipy_find_peaks

from cvmeasure.part.peaks import find_peaks


def _signals(rng: np.random.Generator):
    """Random signals of the kinds the chord counter sees and the corner cases: noise,
    quantised noise (plateaus and equal peak heights), sharp peaks on a floor, constant
    runs at the ends, very short signals."""
    for n in (0, 1, 2, 3, 4, 5, 7, 20, 200, 1500):
        for _ in range(16):
            kind = rng.integers(4)
            if kind == 0:
                x = rng.normal(size=n)
            elif kind == 1:
                x = np.round(rng.normal(size=n) * rng.uniform(0.5, 3.0))
            elif kind == 2:
                x = np.abs(rng.normal(scale=0.1, size=n))
                for p in rng.integers(0, max(n, 1), size=rng.integers(0, 12)):
                    x[p : p + rng.integers(1, 4)] += rng.choice([2.0, 3.0, 5.0])
            else:
                x = rng.integers(0, 3, size=n).astype(float)
                if n > 4:
                    x[: rng.integers(1, 3)] = 2.0
                    x[-rng.integers(1, 3) :] = 2.0
            yield x


def test_same_peaks_as_scipy_on_random_signals() -> None:
    rng = np.random.default_rng(40)
    cases = 0
    for x in _signals(rng):
        for height in (-np.inf, 0.0, 1.0, 2.5):
            for distance in (1, 1.5, 2, 3, 7, 24, 400):
                want = scipy_find_peaks(x, height=height, distance=distance)[0]
                got = find_peaks(x, height=height, distance=distance)
                np.testing.assert_array_equal(got, want, err_msg=f"{x!r} {height} {distance}")
                assert got.dtype == want.dtype
                cases += 1
    assert cases == 10 * 16 * 4 * 7


def test_not_a_number_samples_are_never_peaks_nor_block_their_neighbours() -> None:
    x = np.array([0.0, 1.0, np.nan, 2.0, 0.5, np.nan, np.nan, 3.0, 1.0, 4.0, 0.0])
    for distance in (1, 2, 3):
        want = scipy_find_peaks(x, height=0.0, distance=distance)[0]
        np.testing.assert_array_equal(find_peaks(x, height=0.0, distance=distance), want)


@pytest.mark.parametrize("distance", [0, 0.5, np.nan])
def test_spacing_below_one_sample_is_refused(distance: float) -> None:
    with pytest.raises(ValueError, match="distance"):
        find_peaks(np.zeros(5), height=0.0, distance=distance)
