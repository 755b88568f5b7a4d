"""σ_pt in robust mode at a point whose s* is 0: the point's own prescribed σ_pt is used
there and the run succeeds; without one the run fails naming the point
(docs/domain.md §5.7)."""

import numpy as np
import pytest

from analysis.core.groups import Groups
from analysis.core.robust import DegenerateScaleError, sigma_pt_robust
from analysis.models import AssignedValue, Score
from analysis.services import analysis_run_start
from labs.models import Result
from proficiency.models import Comparison


def test_core_gives_nan_where_a_zero_s_star_is_not_needed():
    x = np.array([1.0, 2.0, 3.5, 5.0, 7.0, 7.0, 7.0, 7.0])
    groups = Groups.from_index(np.array([0, 0, 0, 0, 1, 1, 1, 1]), 2)
    with pytest.raises(DegenerateScaleError) as err:
        sigma_pt_robust(x, groups)
    assert err.value.groups == (1,)
    s = sigma_pt_robust(x, groups, needed=np.array([True, False]))
    assert np.isnan(s[1]) and s[0] > 0
    assert s[0] == sigma_pt_robust(x[:4], Groups.from_index(np.zeros(4, int), 1))[0]


@pytest.fixture
def demo(demo):
    """The demo round (tests/analysis/conftest.py) with Algorithm A and a robust σ_pt."""
    Comparison.objects.filter(pk=demo.pk).update(
        assigned_value_method="algorithm_a", sigma_pt_mode="robust", sigma_pt_value=None
    )
    demo.refresh_from_db()
    return demo


def sigmas(run) -> dict[int, float | None]:
    rows = AssignedValue.objects.filter(run=run).values_list("measurement_point_id", "sigma_pt")
    return dict(rows)


@pytest.mark.django_db(transaction=True)
def test_a_prescribed_sigma_pt_rescues_a_point_whose_s_star_is_zero(demo):
    before = analysis_run_start(comparison=demo, user=None)
    before.refresh_from_db()
    assert before.status == "succeeded", before.error
    point = demo.measurement_points.order_by("pk")[4]
    Result.objects.filter(measurement_point=point).update(value=418.0)

    failed = analysis_run_start(comparison=demo, user=None)
    failed.refresh_from_db()
    assert failed.status == "failed"
    assert f"σ_pt cannot be the robust s* at {point}: s* is 0 there" in failed.error

    point.sigma_pt_value = 2.5
    point.save()
    run = analysis_run_start(comparison=demo, user=None)
    run.refresh_from_db()
    assert run.status == "succeeded", run.error
    now, then = sigmas(run), sigmas(before)
    assert now[point.pk] == 2.5
    del now[point.pk], then[point.pk]
    assert now == then and len(now) == 80  # every other point keeps its s*
    z = Score.objects.filter(run=run, result__measurement_point=point).values_list("z", flat=True)
    assert len(z) == 11 and set(z) == {0.0}  # identical results at x_pt = 418: z = 0/2.5
