"""The patient's true cuffs scattered around the published ones (exo_ctrl/plant/cuff_scatter.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import truncnorm

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plant import CuffParams
from exo_ctrl.plant.cuff_scatter import DEFAULT_SPREAD, CuffScatter

#: The cited spread (module docstring: 18 % and 21 % inter-subject coefficients of variation).
CITED = (0.18, 0.21)


def test_the_default_spread_is_within_the_cited_ones() -> None:
    assert CITED[0] <= DEFAULT_SPREAD <= CITED[1]
    assert CuffScatter().spread_rel == DEFAULT_SPREAD


def test_the_draw_is_seeded() -> None:
    assert CuffScatter(seed=4).factors() == CuffScatter(seed=4).factors()
    assert CuffScatter(seed=4).factors() != CuffScatter(seed=5).factors()
    # The first two accepted standard normals of numpy's generator for the seed.
    rng = np.random.default_rng(7)
    z = [x for x in rng.standard_normal(50) if abs(x) <= 2.0][:2]
    assert CuffScatter(seed=7).factors() == pytest.approx((1 + 0.2 * z[0], 1 + 0.2 * z[1]))


def test_the_factors_stay_within_two_spreads_and_scatter_as_the_truncated_normal() -> None:
    """Over 2000 patients: factors in [1 − 2s, 1 + 2s]; mean 1, SD s·σ_trunc; f_n, f_u apart."""
    f = np.array([CuffScatter(seed=s).factors() for s in range(2000)])
    s = DEFAULT_SPREAD
    assert np.all(f >= 1.0 - 2.0 * s) and np.all(f <= 1.0 + 2.0 * s)
    sd = s * truncnorm.std(-2.0, 2.0)  # 0.176 for s = 0.2
    np.testing.assert_allclose(f.mean(axis=0), 1.0, atol=3.0 * sd / math.sqrt(2000))
    np.testing.assert_allclose(f.std(axis=0), sd, rtol=0.06)
    assert abs(np.corrcoef(f.T)[0, 1]) < 0.08  # independent draws


def test_apply_scales_stiffness_and_keeps_each_damping_ratio() -> None:
    published = CuffParams(preload_N=5.0)
    scatter = CuffScatter(seed=6)
    f_n, f_u = scatter.factors()
    true = scatter.apply(published)
    assert true.stiffness_N_per_m == pytest.approx(f_n * 8000.0, rel=1e-15)
    assert true.shear_stiffness_N_per_m == pytest.approx(f_u * 3700.0, rel=1e-15)
    # ζ = C / (2 √(k m)): C scaled by √f keeps it.
    assert true.damping_N_s_per_m / math.sqrt(true.stiffness_N_per_m) == pytest.approx(
        100.0 / math.sqrt(8000.0), rel=1e-12
    )
    assert true.shear_damping_N_s_per_m / math.sqrt(true.shear_stiffness_N_per_m) == pytest.approx(
        70.0 / math.sqrt(3700.0), rel=1e-12
    )
    assert true.preload_N == 5.0
    assert CuffScatter.exact().apply(published) is published
    assert CuffScatter.exact().factors() == (1.0, 1.0)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"spread_rel": -0.1}, "cuff_scatter spread_rel must be in [0, 0.45]; got -0.1"),
        ({"spread_rel": 0.5}, "cuff_scatter spread_rel must be in [0, 0.45]; got 0.5"),
        ({"seed": -1}, "cuff_scatter seed must be an integer >= 0; got -1"),
        ({"seed": 1.5}, "cuff_scatter seed must be an integer >= 0; got 1.5"),
        ({"seed": True}, "cuff_scatter seed must be an integer >= 0; got True"),
    ],
)
def test_bad_scatter_is_refused_with_one_line(kwargs, message) -> None:
    with pytest.raises(InvalidParameter) as e:
        CuffScatter(**kwargs)
    assert str(e.value) == message
