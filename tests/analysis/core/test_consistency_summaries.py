"""Mandel's h and k and Cochran's C from cell summaries (mean, sd, n), as a results table
gives them, agree with the same statistics from the replicates themselves."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.core import consistency as c
from analysis.core.groups import CoreInputError, Groups


def _replicates(rng: np.random.Generator, n_points: int, n_labs: int, n: int):
    g = np.repeat(np.arange(n_points), n_labs * n)
    lab = np.tile(np.repeat(np.arange(n_labs), n), n_points)
    x = (
        418
        + rng.normal(0, 1, size=g.size)
        + rng.normal(0, 0.5, size=(n_points, n_labs)).repeat(n, axis=1).reshape(-1)
    )
    return x, lab, Groups.from_index(g)


def test_summaries_give_the_replicates_statistics() -> None:
    rng = np.random.default_rng(7)
    x, lab, groups = _replicates(rng, 4, 9, 5)
    cells = c.cell_statistics(x, lab, groups)
    summary = c.cells_from_summaries(
        cells.mean, cells.sd, cells.n, cells.lab, Groups.from_index(cells.group, 4)
    )
    from_x, from_s = c.mandel(x, lab, groups), c.mandel_cells(summary)
    for name in ("h", "k", "h_critical_5", "h_critical_1", "k_critical_5", "k_critical_1"):
        np.testing.assert_allclose(getattr(from_s, name), getattr(from_x, name), rtol=1e-13)
    assert (from_s.h_code == from_x.h_code).all() and (from_s.k_code == from_x.k_code).all()
    cx, cs = c.cochran(x, lab, groups), c.cochran_cells(summary)
    np.testing.assert_allclose(cs.c, cx.c, rtol=1e-13)
    assert (cs.lab == cx.lab).all() and (cs.p == 9).all() and (cs.n == 5).all()


def test_cells_without_repeats_take_part_in_h_only() -> None:
    mean = [1.0, 2.0, 3.5, 2.2]
    cells = c.cells_from_summaries(mean, [0.1, 0.2, 0.0, 0.3], [3, 3, 1, 3], [0, 1, 2, 3],
                                   Groups.from_index([0, 0, 0, 0]))  # fmt: skip
    m = c.mandel_cells(cells)
    means = np.array(mean)
    np.testing.assert_allclose(m.h, (means - means.mean()) / means.std(ddof=1), rtol=1e-14)
    sds = np.array([0.1, 0.2, 0.3])
    np.testing.assert_allclose(m.k[[0, 1, 3]], sds * np.sqrt(3) / np.sqrt((sds**2).sum()))
    assert m.k[2] == 0 and not m.k_tested[2] and m.p[0] == 4
    assert c.cochran_cells(cells).p[0] == 3


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (([1.0], [0.1], [1], [0]), "sd must be 0"),
        (([1.0], [-0.1], [3], [0]), "sd must be >= 0"),
        (([1.0], [0.1], [2.5], [0]), "n integers >= 1"),
        (([1.0, 2.0], [0.1, 0.1], [3, 3], [0, 0]), "one cell per group"),
        (([np.nan], [0.1], [3], [0]), r"mean\[0\] must be finite"),
        (([1.0], [0.1], [3, 3], [0]), "same length"),
    ],
)
def test_bad_summaries(
    args: tuple[list[float], list[float], list[float], list[int]], message: str
) -> None:
    size = len(args[0])
    with pytest.raises(CoreInputError, match=message):
        c.cells_from_summaries(*args, Groups.from_index(np.zeros(size, dtype=int)))
