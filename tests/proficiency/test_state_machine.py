"""The comparison and submission life cycles: every legal move works, every other is refused."""

import itertools

import pytest

from common.errors import InvalidTransition
from labs.models import Submission
from labs.services import SUBMISSION_TRANSITIONS, submission_transition
from proficiency.models import Comparison, ComparisonStatus
from proficiency.services import COMPARISON_TRANSITIONS, comparison_transition
from tests.factories import ComparisonFactory, MeasurementPointFactory, SubmissionFactory

pytestmark = pytest.mark.django_db

LEGAL = {
    ("draft", "open"),
    ("open", "closed"),
    ("closed", "open"),
    ("closed", "analysed"),
    ("analysed", "closed"),
    ("analysed", "published"),
}
ALL_PAIRS = list(itertools.product(ComparisonStatus.values, repeat=2))


def test_transition_table_is_the_documented_life_cycle():
    table = {(a, b) for a, nexts in COMPARISON_TRANSITIONS.items() for b in nexts}
    assert table == LEGAL


def with_points(status: str) -> Comparison:
    c = ComparisonFactory.create(status=status)
    MeasurementPointFactory.create(device__comparison=c)
    return c


@pytest.mark.parametrize("frm,to", sorted(LEGAL))
def test_legal_transition(frm, to):
    c = with_points(frm)
    comparison_transition(comparison=c, to=to)
    c.refresh_from_db()
    assert c.status == to


@pytest.mark.parametrize("frm,to", [p for p in ALL_PAIRS if p not in LEGAL])
def test_illegal_transition_refused_with_clear_message(frm, to):
    c = with_points(frm)
    with pytest.raises(InvalidTransition) as err:
        comparison_transition(comparison=c, to=to)
    assert f"cannot go from {frm} to {to}" in err.value.message
    assert c.code in err.value.message
    assert err.value.status_code == 409
    c.refresh_from_db()
    assert c.status == frm


def test_published_is_final_and_says_so():
    c = with_points("published")
    with pytest.raises(InvalidTransition, match="none \\(published is final\\)"):
        comparison_transition(comparison=c, to="closed")


def test_unknown_status_refused():
    c = with_points("draft")
    with pytest.raises(InvalidTransition, match="Unknown comparison status 'finished'"):
        comparison_transition(comparison=c, to="finished")


def test_cannot_open_without_measurement_points():
    c = ComparisonFactory.create(status="draft")
    with pytest.raises(InvalidTransition, match="no measurement points"):
        comparison_transition(comparison=c, to="open")
    c.refresh_from_db()
    assert c.status == "draft"


SUB_LEGAL = {("draft", "submitted"), ("submitted", "accepted"), ("submitted", "rejected")}


def test_submission_table():
    table = {(a, b) for a, nexts in SUBMISSION_TRANSITIONS.items() for b in nexts}
    assert table == SUB_LEGAL


@pytest.mark.parametrize("frm,to", list(itertools.product(Submission.Status.values, repeat=2)))
def test_submission_transitions(frm, to):
    s = SubmissionFactory.create(status=frm)
    if (frm, to) in SUB_LEGAL:
        submission_transition(submission=s, to=to, message="checked")
        s.refresh_from_db()
        assert s.status == to
        stamp = s.submitted_at if to == "submitted" else s.decided_at
        assert stamp is not None and stamp.tzinfo is not None
    else:
        with pytest.raises(InvalidTransition, match=f"cannot go from {frm} to {to}"):
            submission_transition(submission=s, to=to)
        s.refresh_from_db()
        assert s.status == frm
