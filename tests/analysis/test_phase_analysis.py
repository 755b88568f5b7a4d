"""Phases in the analysis (docs/domain.md §12): the consensus on phases unwrapped about the
circular mean, D wrapped, En on the wrapped D, matrices on wrapped differences, R̄ = 0 named.
Every expected number is computed here by hand (or by scipy), not by the code under test.
No database."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.stats import circmean

from analysis import circular as circ
from analysis.core.groups import CoreInputError, Groups
from analysis.offline import render
from analysis.pipeline import AssignedSpec, ResultTable, analyse, to_json
from labs.importers import ResultRow


def rows(values, us, *, quantity="phase", labs=None, k=2.0, frequency=80.0):
    labs = labs or [f"L{i + 1:02d}" for i in range(len(values))]
    return [
        ResultRow(row=i + 2, lab=lab, device="MEMS 1", axis="X", frequency_hz=frequency,
                  bench="curvilinear", direction="tangential", quantity=quantity,
                  sensitivity=x, unit="deg", expanded_uncertainty=k * u, coverage_factor=k)
        for i, (lab, x, u) in enumerate(zip(labs, values, us, strict=True))
    ]  # fmt: skip


def wrap(a):
    """(−180°, 180°], written here independently of the code under test."""
    r = math.fmod(a + 180.0, 360.0)
    r = r + 360.0 if r < 0 else r
    return 180.0 if r == 0.0 else r - 180.0


def test_weighted_mean_across_plus_minus_180():
    x, u = [179.0, -179.0, 178.0], [1.5, 1.5, 3.0]
    a = analyse(ResultTable.from_rows(rows(x, u)), AssignedSpec.parse("weighted-mean"))
    # by hand: the phases are 179, 181, 178 on a line; weights 1/u² = 4/9, 4/9, 1/9 (χ² 1.3)
    w = np.array([4.0, 4.0, 1.0]) / 9
    mean = (4 * 179 + 4 * 181 + 1 * 178) / 9  # 179.777…
    assert a.assigned.value[0] == pytest.approx(wrap(mean), abs=1e-12)
    assert a.assigned.standard_uncertainty[0] == pytest.approx(1 / math.sqrt(w.sum()), rel=1e-12)
    d = [wrap(xi - mean) for xi in x]  # 179 − 179.78 = −0.78; −179 − 179.78 → +1.22
    np.testing.assert_allclose(a.scores.d, d, rtol=0, atol=1e-12)
    assert d[1] == pytest.approx(1.2222222222, abs=1e-9)
    # En with the Cox correction (each result is in the weighted mean): U_d = 2·√(u² − u_pt²)
    u_pt2 = 1 / w.sum()
    en = [di / (2 * math.sqrt(ui**2 - u_pt2)) for di, ui in zip(d, u, strict=True)]
    np.testing.assert_allclose(a.scores.en, en, rtol=1e-12)
    assert np.isnan(a.scores.d_percent).all()  # a per cent of an angle means nothing


def test_centre_is_the_circular_mean_as_scipy_computes_it():
    x = np.array([179.0, -179.0, 178.0, -175.5, 176.0])
    groups = Groups.from_index(np.zeros(5, dtype=np.intp), 1)
    linear, no_centre = circ.linear_values(x, np.ones(5, dtype=bool), groups)
    centre = math.degrees(circmean(np.radians(x), high=math.pi, low=-math.pi))
    assert not no_centre.any()
    # each phase is laid next to the centre: within ±180° of it, equal modulo 360°
    assert (np.abs(linear - centre) <= 180).all()
    np.testing.assert_allclose(np.mod(linear - x, 360.0), 0.0, atol=1e-12)
    assert linear.tolist() == [179.0, 181.0, 178.0, 184.5, 176.0]


def test_reference_laboratory_and_en_on_the_wrapped_difference():
    x, u = [-179.0, 179.5, 170.0], [0.25, 0.5, 1.0]
    table = ResultTable.from_rows(rows(x, u))
    a = analyse(table, AssignedSpec.parse("reference:L01"))
    assert a.assigned.value[0] == -179.0
    d2, d3 = wrap(179.5 + 179.0), wrap(170.0 + 179.0)  # −1.5 and −11
    assert (d2, d3) == (-1.5, -11.0)
    np.testing.assert_allclose(a.scores.d, [0.0, d2, d3], atol=1e-12)
    assert a.scores.en[1] == pytest.approx(d2 / math.hypot(1.0, 0.5), rel=1e-12)
    assert a.scores.en[2] == pytest.approx(d3 / math.hypot(2.0, 0.5), rel=1e-12)


def test_a_phase_consensus_of_zero_degrees_is_scored():
    # x_pt = 0° is an ordinary phase (D% is not formed): no "x_pt is 0" error
    a = analyse(ResultTable.from_rows(rows([-1.0, 1.0], [0.5, 0.5])), AssignedSpec.parse("median"))
    assert a.assigned.value[0] == 0.0
    np.testing.assert_allclose(a.scores.d, [-1.0, 1.0])


def test_magnitudes_beside_phases_keep_their_numbers():
    phases = rows([179.0, -179.0, 178.0], [0.5, 0.5, 1.0])
    magnitudes = rows([418.0, 420.0, 419.0], [1.0, 1.0, 2.0], quantity="magnitude")
    spec = AssignedSpec.parse("weighted-mean")
    alone = analyse(ResultTable.from_rows(magnitudes), spec)
    both = analyse(ResultTable.from_rows(magnitudes + phases), spec)
    assert [p[5] for p in both.points] == ["magnitude", "phase"]
    assert both.assigned.value[0] == alone.assigned.value[0]
    np.testing.assert_array_equal(both.scores.d_percent[:3], alone.scores.d_percent)
    doc = json.loads(render(both, "json"))
    assert [r["quantity"] for r in doc["assigned_values"]] == ["magnitude", "phase"]
    assert doc["scores"][3]["d_percent"] is None and doc["scores"][0]["d_percent"] is not None
    assert [r["quantity"] for r in to_json(both)["scores"]] == ["magnitude"] * 3 + ["phase"] * 3


def test_compatibility_matrix_of_phases_uses_wrapped_differences():
    # two labs at two frequencies; the frequency matrix pools labs per frequency
    table = ResultTable.from_rows(
        rows([179.0, -179.0], [0.5, 0.5], frequency=10.0)
        + rows([-178.0, -178.0], [0.5, 0.5], frequency=20.0)
    )
    a = analyse(table, AssignedSpec.parse("weighted-mean"), compare=[("frequency", None)])
    (m,) = a.compatibility
    assert m.group == {"device": "MEMS 1", "axis": "X", "quantity": "phase"}
    # level means 180 (179, 181) and −178; the difference is 2°, not 358°
    assert m.value.tolist() == pytest.approx([180.0, -178.0])
    u10 = math.hypot(0.5, math.sqrt(2.0))  # ū with the spread s = √2 of 179 and 181
    expected = 2.0 / math.hypot(2 * u10, 2 * 0.5)
    assert m.en[0, 1] == pytest.approx(expected, rel=1e-12)


def test_phases_pointing_every_way_are_named_not_averaged():
    table = ResultTable.from_rows(rows([0.0, 120.0, -120.0], [1.0, 1.0, 1.0]))
    with pytest.raises(CoreInputError, match="point in every direction") as caught:
        analyse(table, AssignedSpec.parse("weighted-mean"))
    assert "MEMS 1 X 80 Hz curvilinear tangential sensitivity phase" in str(caught.value)
    # a reference laboratory needs no centre: it is scored
    a = analyse(table, AssignedSpec.parse("reference:L01"))
    np.testing.assert_allclose(a.scores.d, [0.0, 120.0, -120.0], atol=1e-12)
