"""The public landing page (a lab member's dashboard is labs.views.home)."""

from django.conf import settings
from django.http import HttpRequest, HttpResponse
from django.shortcuts import render

from proficiency.selectors import comparisons_visible_to


def home(request: HttpRequest) -> HttpResponse:
    comparisons = comparisons_visible_to(request.user).order_by("code")
    return render(
        request,
        "home.html",
        {"comparisons": comparisons, "provider": settings.PT_PROVIDER_NAME},
    )
