"""Read-side queries of the comparison domain; each owns its joins."""

from __future__ import annotations

from django.contrib.auth.models import AnonymousUser, User
from django.db.models import Q, QuerySet

from proficiency.models import Comparison


def comparisons_visible_to(user: User | AnonymousUser) -> QuerySet[Comparison]:
    """Comparisons a user may see: superusers all; coordinators theirs; lab members
    those their laboratory takes part in. Anonymous users see none."""
    if not user.is_authenticated:
        return Comparison.objects.none()
    if user.is_superuser:
        return Comparison.objects.all()
    return Comparison.objects.filter(
        Q(coordinators=user) | Q(participants__laboratory__members__user=user)
    ).distinct()
