"""Password reset, throttled like sign-in.

Django's ``PasswordResetView`` sends a reset e-mail to whatever address is typed in, as
often as asked: a mail bomb for that address, and free guesses of which addresses have an
account. Here every reset that would send an e-mail counts once for the client address
(``common.middleware.client_ip``, the same as the sign-in lockout's) and once for the
e-mail address typed in, in the shared cache; past ``PASSWORD_RESET_LIMIT`` for either
within ``PASSWORD_RESET_WINDOW`` the page answers 429 and sends nothing.
"""

from __future__ import annotations

import hashlib
from typing import Any

from django.conf import settings
from django.contrib.auth import views as auth_views
from django.core.cache import cache
from django.http import HttpResponse
from django.shortcuts import render

from common.middleware import client_ip


def _count(key: str, window: int) -> int:
    """One more attempt for ``key`` in a window that starts at its first attempt."""
    cache.add(key, 0, timeout=window)
    try:
        return int(cache.incr(key))
    except ValueError:  # expired between add and incr
        cache.set(key, 1, timeout=window)
        return 1


def reset_attempts(address: str, email: str) -> int:
    """Count an attempt for the client address and for the e-mail address; the larger count."""
    window = int(settings.PASSWORD_RESET_WINDOW.total_seconds())
    target = hashlib.sha256(email.strip().casefold().encode()).hexdigest()
    return max(
        _count(f"password-reset:address:{address}", window),
        _count(f"password-reset:email:{target}", window),
    )


class PasswordResetView(auth_views.PasswordResetView):
    def form_valid(self, form: Any) -> HttpResponse:
        if reset_attempts(client_ip(self.request), form.cleaned_data["email"]) > int(
            settings.PASSWORD_RESET_LIMIT
        ):
            context = {
                "limit": settings.PASSWORD_RESET_LIMIT,
                "minutes": int(settings.PASSWORD_RESET_WINDOW.total_seconds() // 60),
            }
            return render(
                self.request, "registration/password_reset_throttled.html", context, status=429
            )
        return super().form_valid(form)
