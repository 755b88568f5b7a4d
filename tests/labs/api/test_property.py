"""Property: malformed JSON results never store anything and never give a 500."""

import pytest
from django.core.cache import cache
from django.db import transaction
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from labs.importers import COLUMNS
from labs.models import Result, Submission
from tests.labs.api import build_world, rows

pytestmark = pytest.mark.django_db

SUBMIT = "/api/v1/comparisons/IMU-A-01/submissions/"

scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(10**6), max_value=10**6),
    st.floats(allow_nan=False, allow_infinity=False),
    st.text(max_size=12),
    st.sampled_from(["nan", "inf", "-1", "0", "1e400", "2%", "-2%", "MEMS 1", "X", "linear"]),
)
json_values = st.recursive(
    scalars,
    lambda inner: st.lists(inner, max_size=3)
    | st.dictionaries(st.text(max_size=5), inner, max_size=3),
    max_leaves=6,
)
# A field set to a value that can never be valid for this comparison.
BAD: dict[str, list[object]] = {
    "sensitivity": [-1, 0, "nan", "inf", "abc", "", None, [], {}],
    "expanded_uncertainty": [0, -3, "-2%", "abc", "", None],
    "coverage_factor": [0, -1, "k", "nan"],
    "axis": ["W", "", 1, None],
    "device": ["NOPE", "", None, 5],
    "frequency_hz": [0, -5, 7, "x", None],
    "bench": ["rotary", "", None],
    "direction": ["radial", "sideways"],
    "note": ["n" * 501],
    "lab": ["L01"],
    "sensitivty": [420],
}
bad_row = st.builds(
    lambda base, field, choice: {**base, field: BAD[field][choice % len(BAD[field])]},
    st.sampled_from(rows()),
    st.sampled_from(sorted(BAD)),
    st.integers(min_value=0, max_value=20),
)
missing_required = st.builds(
    lambda base, field: {k: v for k, v in base.items() if k != field},
    st.sampled_from(rows()),
    st.sampled_from(
        ["device", "axis", "frequency_hz", "bench", "sensitivity", "expanded_uncertainty"]
    ),
)
any_row = st.one_of(
    st.sampled_from(rows()),
    st.dictionaries(st.sampled_from([*COLUMNS, "x", "Sensitivity"]), scalars, max_size=8),
    json_values,
)
payload = st.one_of(
    st.builds(
        lambda good, bad, at: [*good[:at], bad, *good[at:]],
        st.lists(any_row, max_size=6),
        st.one_of(bad_row, missing_required, scalars),
        st.integers(min_value=0, max_value=6),
    ).map(lambda results: {"results": results}),
    st.dictionaries(st.sampled_from(["results", "submit", "x"]), json_values, max_size=3).filter(
        lambda body: not isinstance(body.get("results"), list)
    ),
)


@pytest.fixture
def world():
    cache.clear()
    return build_world()


@settings(
    max_examples=50,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(body=payload, submit=st.sampled_from([True, False, None]))
def test_malformed_rows_store_nothing_and_never_500(world, body, submit):
    if submit is not None and isinstance(body, dict) and "submit" not in body:
        body = {**body, "submit": submit}
    counts = (Submission.objects.count(), Result.objects.count())
    with transaction.atomic():  # each example leaves the database as it found it
        response = world.client("key_a").post(SUBMIT, body, format="json")
        after = (Submission.objects.count(), Result.objects.count())
        transaction.set_rollback(True)
    assert response.status_code == 400, (body, response.content[:300])
    answer = response.json()
    assert set(answer) == {"detail", "errors"} and answer["detail"]
    assert all(set(e) == {"row", "field", "message"} for e in answer["errors"])
    assert after == counts
