"""Anonymous participant codes: unique per comparison, random, not derived from the lab."""

import re

import pytest

from labs.models import Participant
from labs.services import participant_add, participant_code_new
from tests.factories import ComparisonFactory, LaboratoryFactory, ParticipantFactory

pytestmark = pytest.mark.django_db


def test_codes_are_unique_and_well_formed():
    comparison = ComparisonFactory.create()
    labs = LaboratoryFactory.create_batch(40)
    codes = [participant_add(comparison=comparison, laboratory=lab).code for lab in labs]
    assert len(set(codes)) == 40
    assert all(re.fullmatch(r"L\d\d", c) for c in codes)


def test_adding_twice_returns_the_same_participant():
    comparison, lab = ComparisonFactory.create(), LaboratoryFactory.create()
    first = participant_add(comparison=comparison, laboratory=lab)
    assert participant_add(comparison=comparison, laboratory=lab) == first
    assert Participant.objects.count() == 1


def test_codes_are_not_derived_from_the_lab():
    """The same labs joining 30 comparisons in the same order get varying codes."""
    labs = LaboratoryFactory.create_batch(5)
    per_lab: dict[int, set[str]] = {lab.pk: set() for lab in labs}
    for _ in range(30):
        comparison = ComparisonFactory.create()
        for lab in labs:
            per_lab[lab.pk].add(participant_add(comparison=comparison, laboratory=lab).code)
    # A deterministic scheme (join order, lab id, name hash) would give 1 code per lab.
    assert all(len(codes) > 5 for codes in per_lab.values())
    # Codes are not handed out in join order: with random codes the 5 labs come out
    # sorted in about 1 comparison of 120; a sequential scheme would sort all 30.
    in_join_order = 0
    for comparison in {p.comparison for p in Participant.objects.select_related("comparison")}:
        codes = list(
            comparison.participants.order_by("invited_at", "pk").values_list("code", flat=True)
        )
        in_join_order += codes == sorted(codes)
    assert in_join_order < 5


def test_codes_grow_to_three_digits_when_two_are_used_up():
    comparison = ComparisonFactory.create()
    for n in range(1, 100):
        ParticipantFactory.create(comparison=comparison, code=f"L{n:02d}")
    code = participant_code_new(comparison=comparison)
    assert re.fullmatch(r"L\d{3}", code)
