"""Read-side queries of the comparison domain; each owns its joins."""

from __future__ import annotations

from django.contrib.auth.models import AbstractBaseUser, AnonymousUser
from django.db.models import Q, QuerySet

from proficiency.models import Comparison, MeasurementPoint

#: Rows related to a measurement point in the points' own order (device, axis, frequency, ...).
POINT_ORDER = [f"measurement_point__{f}" for f in MeasurementPoint._meta.ordering]


def comparisons_visible_to(user: AbstractBaseUser | AnonymousUser) -> QuerySet[Comparison]:
    """Comparisons a user may see: superusers all; coordinators theirs; lab members
    those their laboratory takes part in. Anonymous users see none."""
    if not user.is_authenticated:
        return Comparison.objects.none()
    if user.is_superuser:
        return Comparison.objects.all()
    return Comparison.objects.filter(
        Q(coordinators=user) | Q(participants__laboratory__members__user=user)
    ).distinct()
