"""A laboratory's kit pages (docs/domain.md §15): its own slots with each kit's items and
dates, the arrival to log and the dispatch to the next holder. Another laboratory's slot
answers 404; who holds the kit before or after is never shown."""

from __future__ import annotations

from typing import TYPE_CHECKING

from django import forms
from django.contrib import messages
from django.contrib.auth.decorators import login_required
from django.http import Http404, HttpResponse
from django.shortcuts import redirect, render
from django.views.decorators.http import require_GET, require_POST

from common.errors import ApplicationError
from labs import kits
from labs.access import participant_page
from labs.models import Handover, KitSlot, Participant

if TYPE_CHECKING:
    from common.http import AuthenticatedHttpRequest

PHOTO_MAX_BYTES = 5 * 1024 * 1024
PHOTO_MAGIC = (b"\xff\xd8\xff", b"\x89PNG\r\n\x1a\n")


class ArrivalForm(forms.Form):
    condition = forms.ChoiceField(choices=Handover.Condition.choices, label="Condition")
    condition_note = forms.CharField(
        required=False, max_length=kits.MAX_TEXT, label="What is damaged or missing",
        widget=forms.Textarea(attrs={"rows": 2}),
    )  # fmt: skip
    photo = forms.FileField(required=False, label="Photo (JPEG or PNG, optional)")

    def clean_photo(self):
        photo = self.cleaned_data.get("photo")
        if photo is None:
            return None
        if photo.size > PHOTO_MAX_BYTES:
            raise forms.ValidationError(
                f"The photo is larger than {PHOTO_MAX_BYTES // (1024 * 1024)} MiB."
            )
        head = photo.read(8)
        photo.seek(0)
        if not head.startswith(PHOTO_MAGIC):
            raise forms.ValidationError("The photo must be a JPEG or PNG image.")
        return photo


class DispatchForm(forms.Form):
    carrier_note = forms.CharField(
        required=False, max_length=500, label="Carrier and tracking number"
    )


def _own_slot(participant: Participant, pk: int) -> KitSlot:
    slot = KitSlot.objects.filter(participant=participant, pk=pk).select_related("kit").first()
    if slot is None:
        raise Http404("No such slot of yours.")
    return slot


def _page(
    request: AuthenticatedHttpRequest, participant: Participant, **forms_: object
) -> HttpResponse:
    context = {
        "participant": participant,
        "comparison": participant.comparison,
        "slots": kits.own_circulation(participant),
        "arrival_form": forms_.get("arrival_form") or ArrivalForm(),
        "dispatch_form": forms_.get("dispatch_form") or DispatchForm(),
        "failed_slot": forms_.get("failed_slot"),
    }
    return render(request, "labs/kits.html", context, status=400 if forms_ else 200)


@login_required
@require_GET
def kit_page(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    return _page(request, participant_page(request, code))


@login_required
@require_POST
def kit_received(request: AuthenticatedHttpRequest, code: str, pk: int) -> HttpResponse:
    participant = participant_page(request, code)
    slot = _own_slot(participant, pk)
    arrival = Handover.objects.filter(to_slot=slot).first()
    if arrival is None:
        raise Http404("The kit has not been sent to this slot yet.")
    form = ArrivalForm(request.POST, request.FILES)
    if form.is_valid():
        try:
            kits.handover_receive(
                handover=arrival, user=request.user, condition=form.cleaned_data["condition"],
                note=form.cleaned_data["condition_note"], photo=form.cleaned_data["photo"],
            )  # fmt: skip
        except ApplicationError as exc:
            form.add_error(None, exc.message)
        else:
            messages.success(request, f"The arrival of {slot.kit.name} is logged.")
            return redirect("labs:kits", code=code)
    return _page(request, participant, arrival_form=form, failed_slot=slot.pk)


@login_required
@require_POST
def kit_dispatched(request: AuthenticatedHttpRequest, code: str, pk: int) -> HttpResponse:
    participant = participant_page(request, code)
    slot = _own_slot(participant, pk)
    form = DispatchForm(request.POST)
    if form.is_valid():
        try:
            kits.handover_dispatch(kit=slot.kit, from_slot=slot, user=request.user,
                                   carrier_note=form.cleaned_data["carrier_note"])  # fmt: skip
        except ApplicationError as exc:
            form.add_error(None, exc.message)
        else:
            messages.success(request, f"{slot.kit.name} is logged as sent on.")
            return redirect("labs:kits", code=code)
    return _page(request, participant, dispatch_form=form, failed_slot=slot.pk)
