"""The worked examples of ISO 13528:2022 Annex E (and Table B.1), reproduced to the printed
precision: every value within half a unit of its last printed digit.

The input data are the standard's example data (Tables E.1 to E.11); the printed results
are the standard's.  Items the standard prints inconsistently (the third column of
Table E.1, the flags of Table E.6) are not used."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.core.groups import Groups
from analysis.core.homogeneity import expanded_criterion_factors, homogeneity
from analysis.core.robust import algorithm_a, algorithm_s, median_made, median_niqr
from analysis.core.scores import compute_scores

# Table E.1: censored results, values below the limit ignored / deleted
E1_IGNORED = [10, 10, 12, 19, 20, 20, 23, 23, 25, 25, 26, 28, 28, 30, 28, 29, 30, 30, 31, 32, 32,
              45, 50]  # fmt: skip
E1_DELETED = [12, 19, 20, 23, 23, 25, 25, 26, 28, 28, 28, 29, 30, 30, 31, 32, 32, 45]
# Table E.2: arsenic in chocolate, 10 items in duplicate
E2 = [[0.185, 0.194], [0.187, 0.189], [0.182, 0.186], [0.188, 0.196], [0.191, 0.181],
      [0.188, 0.180], [0.187, 0.196], [0.177, 0.186], [0.179, 0.187], [0.188, 0.196]]  # fmt: skip
# Table E.4: atrazine in drinking water, 34 participants
E3 = [0.040, 0.055, 0.178, 0.202, 0.206, 0.227, 0.228, 0.230, 0.230, 0.235, 0.236, 0.237, 0.243,
      0.244, 0.245, 0.2555, 0.260, 0.264, 0.267, 0.270, 0.273, 0.274, 0.274, 0.278, 0.2811, 0.287,
      0.287, 0.288, 0.289, 0.295, 0.296, 0.311, 0.331, 0.4246]  # fmt: skip
# Tables E.6/E.7: mercury in feed; x_pt, U(x_pt) (k = 2), sigma_pt; per participant
# value, U, k and the printed D%, z, z', zeta, En
E4_XPT, E4_BIG_U, E4_SIGMA = 0.044, 0.0082, 0.0066
E4 = [
    (0.013, 0.003, 2, -70.5, -4.70, -3.99, -7.10, -3.55),
    (0.013, 0.007, 2, -70.5, -4.70, -3.99, -5.75, -2.88),
    (0.0135, 0.00108, 1.732, -69.3, -4.62, -3.93, -7.35, -3.69),
    (0.014, 0.004, 2, -68.2, -4.55, -3.86, -6.58, -3.29),
    (0.014, 0.0005, 2, -68.2, -4.55, -3.86, -7.30, -3.65),
    (0.016, 0.003, 2, -63.6, -4.24, -3.60, -6.41, -3.21),
    (0.017, 0.008, 2, -61.4, -4.09, -3.47, -4.71, -2.36),
    (0.019, 0.003, 2, -56.8, -3.79, -3.22, -5.73, -2.86),
    (0.0239, 0.0036, 2, -45.7, -3.05, -2.59, -4.49, -2.24),
    (0.037, 0.013, 2, -15.9, -1.06, -0.90, -0.91, -0.46),
    (0.039, 0.007, 2, -11.4, -0.76, -0.64, -0.93, -0.46),
    (0.040, 0.008, 2, -9.1, -0.61, -0.51, -0.70, -0.35),
    (0.040, 0.030, 2, -9.1, -0.61, -0.51, -0.26, -0.13),
    (0.040, 0.010, 2, -9.1, -0.61, -0.51, -0.62, -0.31),
    (0.0424, 0.008, 2, -3.6, -0.24, -0.21, -0.28, -0.14),
    (0.044, 0.007, 2, 0.0, 0.00, 0.00, 0.00, 0.00),
    (0.045, 0.007, 2, 2.3, 0.15, 0.13, 0.19, 0.09),
    (0.045, 0.005, 2, 2.3, 0.15, 0.13, 0.21, 0.10),
    (0.046, 0.007, 2, 4.5, 0.30, 0.26, 0.37, 0.19),
    (0.049, 0.0072, 2, 11.4, 0.76, 0.64, 0.92, 0.46),
    (0.053, 0.007, 2, 20.5, 1.36, 1.16, 1.67, 0.83),
]
# Table E.11: averages and standard deviations of four replicates, 25 participants
E13_AVG = [2.15, 1.85, 1.80, 1.80, 1.90, 1.90, 1.90, 2.05, 2.35, 2.03, 2.08, 1.25, 1.13, 1.00,
           1.08, 1.20, 1.35, 1.23, 1.23, 0.90, 1.48, 1.20, 1.73, 1.43, 1.28]  # fmt: skip
E13_SD = [0.13, 0.21, 0.08, 0.24, 0.36, 0.32, 0.14, 0.26, 0.39, 0.53, 0.25, 0.24, 0.72, 0.26,
          0.17, 0.32, 0.4, 0.36, 0.33, 0.43, 0.40, 0.55, 0.39, 0.30, 0.22]  # fmt: skip
# Table B.1: g -> (F1, F2)
TABLE_B1 = {20: (1.59, 0.57), 19: (1.60, 0.59), 18: (1.62, 0.62), 17: (1.64, 0.64),
            16: (1.67, 0.68), 15: (1.69, 0.71), 14: (1.72, 0.75), 13: (1.75, 0.80),
            12: (1.79, 0.86), 11: (1.83, 0.93), 10: (1.88, 1.01), 9: (1.94, 1.11),
            8: (2.01, 1.25), 7: (2.10, 1.43)}  # fmt: skip


def printed(computed: float, value: float, decimals: int) -> None:
    """``computed`` rounds to the printed ``value`` (half a unit of the last digit)."""
    assert abs(computed - value) <= 0.5 * 10.0**-decimals + 1e-12, (computed, value)


def one(x: list[float]) -> tuple[np.ndarray, Groups]:
    return np.asarray(x, dtype=float), Groups.from_index([0] * len(x))


@pytest.mark.parametrize(
    ("data", "x_star", "s_star"), [(E1_IGNORED, 26.01, 7.23), (E1_DELETED, 26.81, 5.29)]
)
def test_e1_algorithm_a_on_censored_data(data: list[float], x_star: float, s_star: float) -> None:
    """Table E.1 was computed with the standard's stopping rule (third significant figure);
    the converged s* of the first column is 7.2373, which the table would print 7.24."""
    av = algorithm_a(*one(data), stopping="iso2022")
    printed(av.value[0], x_star, 2)
    printed(av.diagnostics["s_star"][0], s_star, 2)
    limit = algorithm_a(*one(data))
    assert (
        abs(limit.value[0] - x_star) < 0.02 and abs(limit.diagnostics["s_star"][0] - s_star) < 0.01
    )


@pytest.mark.parametrize("stopping", ["exact", "iso2022"])
def test_the_other_examples_need_no_particular_stopping_rule(stopping: str) -> None:
    printed(algorithm_a(*one(E3), stopping=stopping).value[0], 0.2570, 4)  # type: ignore[arg-type]
    printed(algorithm_a(*one(E13_AVG), stopping=stopping).value[0], 1.57, 2)  # type: ignore[arg-type]


def test_e2_homogeneity() -> None:
    mean = np.mean(E2)
    h = homogeneity(E2, 0.15 * mean)  # sigma_pt = 15 % of the mean (E.2)
    printed(h.mean[0], 0.18715, 5)
    printed(h.s_x[0], 0.00398, 5)
    printed(h.s_w[0], 0.00556, 5)
    printed(h.s_s[0], 0.00060, 5)
    printed(h.criterion[0], 0.00842, 5)
    assert h.sufficient[0]


def test_e3_median_niqr_made_and_algorithm_a() -> None:
    x, g = one(E3)
    niqr, made = median_niqr(x, g), median_made(x, g)
    printed(niqr.value[0], 0.2620, 4)
    printed(niqr.diagnostics["s_star"][0], 0.0402, 4)
    printed(made.diagnostics["s_star"][0], 0.0386, 4)
    printed(niqr.standard_uncertainty[0], 0.0086, 4)  # Table E.5 prints u from nIQR
    a = algorithm_a(x, g)
    printed(a.value[0], 0.2570, 4)
    printed(a.diagnostics["s_star"][0], 0.0395, 4)
    printed(a.standard_uncertainty[0], 0.0085, 4)


def test_e4_scores() -> None:
    x, big_u, k, d_pct, z, z_prime, zeta, en = (
        np.array(c, dtype=float) for c in zip(*E4, strict=True)
    )
    s = compute_scores(
        x, big_u / k, big_u, Groups.from_index([0] * x.size), E4_XPT, E4_BIG_U / 2,
        U_pt=E4_BIG_U, sigma_pt=E4_SIGMA,
    )  # fmt: skip
    for computed, table, decimals in (
        (s.d_percent, d_pct, 1), (s.z, z, 2), (s.z_prime, z_prime, 2), (s.zeta, zeta, 2),
        (s.en, en, 2),
    ):  # fmt: skip
        for c, t in zip(computed, table, strict=True):
            printed(c, t, decimals)


def test_e7_algorithm_a_of_the_mercury_results() -> None:
    av = algorithm_a(*one([row[0] for row in E4]))
    printed(av.value[0], 0.03161, 5)
    printed(av.diagnostics["s_star"][0], 0.0164, 4)
    printed(av.standard_uncertainty[0], 0.0045, 4)


def test_e13_algorithm_a_of_averages_and_algorithm_s_of_standard_deviations() -> None:
    printed(algorithm_a(*one(E13_AVG)).value[0], 1.57, 2)
    w, g = one(E13_SD)
    printed(algorithm_s(w, g, 3).value[0], 0.34, 2)  # four replicates: nu = 3


@pytest.mark.parametrize("g", sorted(TABLE_B1))
def test_table_b1_factors(g: int) -> None:
    f1, f2 = expanded_criterion_factors(g)
    printed(f1, TABLE_B1[g][0], 2)
    printed(f2, TABLE_B1[g][1], 2)


def test_the_examples_vectorised_together_give_the_same_numbers() -> None:
    """E.1, E.3, E.7 and E.13 in one call, as a round's points are computed."""
    sets = [E1_IGNORED, E1_DELETED, E3, [row[0] for row in E4], E13_AVG]
    x = np.concatenate([np.asarray(s, dtype=float) for s in sets])
    idx = np.repeat(np.arange(len(sets)), [len(s) for s in sets])
    together = algorithm_a(x, Groups.from_index(idx))
    for i, s in enumerate(sets):
        alone = algorithm_a(*one(s))
        assert together.value[i] == alone.value[0]
        assert together.diagnostics["s_star"][i] == alone.diagnostics["s_star"][0]
