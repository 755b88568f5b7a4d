"""Artefact stability in the report (docs/domain.md §7) from the pilot's before/after values,
checked against hand calculations."""

import math

import pytest

from analysis.models import AssignedValue
from analysis.reports.assemble import report_data
from analysis.reports.render import render_report
from common.numbers import uncertainty
from proficiency.models import ReferenceValue
from tests.analysis.reports.conftest import pdf_text

pytestmark = pytest.mark.django_db(transaction=True)
S = ReferenceValue.Source


def test_stability_table_matches_hand_calculation(analysed):
    points = list(analysed.comparison.measurement_points.order_by("pk")[:2])
    stable, drifting = points
    for point, source, value, u in (
        (stable, S.STABILITY_BEFORE, 418.0, 0.5),
        (stable, S.STABILITY_BEFORE, 418.2, 0.5),
        (stable, S.STABILITY_AFTER, 418.3, 0.4),
        (drifting, S.STABILITY_BEFORE, 418.0, 0.1),
        (drifting, S.STABILITY_AFTER, 420.0, 0.1),
    ):
        ReferenceValue.objects.create(
            measurement_point=point, source=source, value=value, standard_uncertainty=u
        )
    data = report_data(run=analysed)
    rows = {data.points[r.point].full_label: r for r in data.stability_rows}
    assert len(rows) == 2
    a = rows[str(stable)]
    # mean of the two before values; u of a mean = rms of the u (consistency.stability_check)
    assert a.before == pytest.approx(418.1) and a.after == pytest.approx(418.3)
    assert a.delta == pytest.approx(0.2)
    assert a.en == pytest.approx(0.2 / (2 * math.sqrt(0.5**2 + 0.4**2)))
    assert a.stable and a.u_stab == 0.0
    b = rows[str(drifting)]
    sigma = AssignedValue.objects.get(run=analysed, measurement_point=drifting).sigma_pt
    assert sigma is not None and 0.3 * sigma < 2.0  # σ_pt = 1 % of ≈ 418: limit ≈ 1.25
    assert b.limit == pytest.approx(0.3 * sigma)
    assert b.en == pytest.approx(2.0 / (2 * math.sqrt(0.02)))
    assert not b.stable and b.u_stab == pytest.approx(2.0 / math.sqrt(3))
    text = " ".join("\n".join(pdf_text(render_report(data))).split())
    assert "2 measurement points; 1 is stable (" in text and "En ≤ 1) and 1 is not." in text
    # Δ with the decimals of the before/after column (6 significant digits of ≈ 420), the
    # limit and u_stab to two significant digits
    limit, u_stab = uncertainty(0.3 * sigma), uncertainty(2 / math.sqrt(3))
    assert f"+2.000 {b.en:.2f} {limit} no {u_stab}" in text
    # the scores use u(x_pt) = u_char (docs/domain.md §5.8): the report must not claim
    # that the drift entered them
    assert "the scores of this round use u(x_pt) = u_char and do not include it" in text
    assert "drift adds" not in text
