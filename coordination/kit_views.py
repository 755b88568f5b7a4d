"""The coordinator's kits page (docs/domain.md §15): the round's kits with their devices by
serial, each kit's circulation plan with what is late, overdue or arrived damaged, and
the provider's two hand-overs (sending a kit out, logging its return)."""

from __future__ import annotations

import datetime as dt
from typing import TYPE_CHECKING

from django import forms
from django.contrib import messages
from django.contrib.auth.decorators import login_required
from django.http import Http404, HttpResponse
from django.shortcuts import redirect, render
from django.views.decorators.http import require_GET, require_POST

from common.errors import ApplicationError, ValidationFailed
from labs import kits
from labs.access import coordinated
from labs.models import Handover, Participant
from proficiency.models import Comparison, Device, Kit

if TYPE_CHECKING:
    from common.http import AuthenticatedHttpRequest

PLAN_HELP = "One line per slot, in loop order: participant code, start date, end date " \
    "(YYYY-MM-DD), e.g. “L07, 2027-01-11, 2027-01-22”."  # fmt: skip


class KitForm(forms.Form):
    name = forms.CharField(max_length=40, label="Name")

    def __init__(self, *args: object, devices: list[Device], **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.devices = devices
        for d in devices:
            self.fields[f"serial_{d.pk}"] = forms.CharField(
                max_length=80, required=False, label=f"Serial of {d.name} (blank: not in the kit)"
            )

    def serials(self) -> dict[Device, str]:
        return {d: self.cleaned_data[f"serial_{d.pk}"] for d in self.devices
                if self.cleaned_data.get(f"serial_{d.pk}", "").strip()}  # fmt: skip


class PlanForm(forms.Form):
    plan = forms.CharField(widget=forms.Textarea(attrs={"rows": 6}), label="Circulation plan",
                           help_text=PLAN_HELP, max_length=100_000)  # fmt: skip


def parse_plan(text: str, comparison: Comparison) -> list[kits.SlotPlan]:
    """The plan's lines as slots; every bad line named (line number, what is wrong)."""
    by_code = {p.code: p for p in Participant.objects.filter(comparison=comparison)}
    plan, errors = [], []
    lines = [line for line in text.splitlines() if line.strip()]
    if len(lines) > kits.MAX_SLOTS:
        raise ValidationFailed(f"A loop holds at most {kits.MAX_SLOTS} slots.")
    for n, line in enumerate(lines, start=1):
        parts = [p.strip() for p in line.split(",")]
        if len(parts) != 3:
            errors.append({"row": n, "message": "give a code, a start date and an end date"})
            continue
        participant = by_code.get(parts[0])
        if participant is None:
            message = f"no participant {parts[0][:20]!r} in this round"
            errors.append({"row": n, "field": "participant", "message": message})
            continue
        try:
            start, end = (dt.date.fromisoformat(p) for p in parts[1:])
        except ValueError:
            errors.append({"row": n, "field": "date", "message": "dates are YYYY-MM-DD"})
            continue
        plan.append(kits.SlotPlan(participant, start, end))
    if errors:
        raise ValidationFailed("The circulation plan has errors.", errors=errors)
    return plan


def _refused(request: AuthenticatedHttpRequest, comparison: Comparison, kit: Kit,
             exc: ApplicationError) -> HttpResponse:  # fmt: skip
    """The kits page again with the refusal under the kit: the message, then each bad line."""
    lines = [exc.message] + [f"line {e['row']}: {e['message']}" if e.get("row") else
                             e["message"] for e in exc.errors]  # fmt: skip
    return _page(request, comparison, status=exc.status_code, plan_errors={kit.pk: lines})


def _next_name(rows: list[dict]) -> str:
    """``Kit A``, ``Kit B``, … : the first such name the round does not use yet."""
    taken = {row["kit"].name for row in rows}
    return next((n for n in (f"Kit {chr(65 + i)}" for i in range(26)) if n not in taken), "")


def _kit(comparison: Comparison, pk: int) -> Kit:
    kit = Kit.objects.filter(comparison=comparison, pk=pk).first()
    if kit is None:
        raise Http404("No such kit in this round.")
    return kit


def _page(request: AuthenticatedHttpRequest, comparison: Comparison, *, status: int = 200,
          kit_form: KitForm | None = None, plan_errors: dict[int, list[str]] | None = None,
          ) -> HttpResponse:  # fmt: skip
    devices = list(comparison.devices.order_by("name"))
    rows = []
    for kit in comparison.kits.prefetch_related("items__device").order_by("name"):
        status_rows = kits.circulation_status(kit)
        rows.append({
            "kit": kit, "slots": status_rows,
            "plan_text": "\n".join(f"{s.slot.participant.code}, {s.slot.starts_on}, "
                                   f"{s.slot.ends_on}" for s in status_rows),
            # the provider's dispatch arrives at the first slot, the last slot's goes back
            "circulating": bool(status_rows) and status_rows[0].arrival is not None,
            "returned": status_rows[-1].departure if status_rows else None,
            "drift": kits.kit_drift(kit), "linking": kits.kit_linking_counts(kit),
        })  # fmt: skip
    context = {
        "comparison": comparison, "kits": rows, "plan_help": PLAN_HELP,
        "kit_form": kit_form or KitForm(devices=devices, initial={"name": _next_name(rows)}),
        "plan_errors": plan_errors or {},
        "conditions": Handover.Condition.choices,
        "measurement_header": ",".join(kits.MEASUREMENT_COLUMNS),
    }  # fmt: skip
    return render(request, "coordinator/kits.html", context, status=status)


@login_required
@require_GET
def kits_page(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    return _page(request, coordinated(request, code))


@login_required
@require_POST
def kit_new(request: AuthenticatedHttpRequest, code: str) -> HttpResponse:
    comparison = coordinated(request, code)
    form = KitForm(request.POST, devices=list(comparison.devices.order_by("name")))
    if form.is_valid():
        try:
            kit = kits.kit_create(comparison_id=comparison.pk, name=form.cleaned_data["name"],
                                  serials=form.serials())  # fmt: skip
        except ApplicationError as exc:
            form.add_error(None, exc.message)
        else:
            messages.success(request, f"{kit.name} is created; give it its circulation plan.")
            return redirect("coordinator:kits", code=code)
    return _page(request, comparison, status=400, kit_form=form)


@login_required
@require_POST
def kit_plan(request: AuthenticatedHttpRequest, code: str, pk: int) -> HttpResponse:
    comparison = coordinated(request, code)
    kit = _kit(comparison, pk)
    form = PlanForm(request.POST)
    try:
        if not form.is_valid():
            raise ValidationFailed("Give the circulation plan, one slot per line.")
        kits.circulation_set(kit=kit, plan=parse_plan(form.cleaned_data["plan"], comparison))
    except ApplicationError as exc:
        return _refused(request, comparison, kit, exc)
    messages.success(request, f"The circulation plan of {kit.name} is saved.")
    return redirect("coordinator:kits", code=code)


@login_required
@require_POST
def kit_dispatch(request: AuthenticatedHttpRequest, code: str, pk: int) -> HttpResponse:
    """The provider sends the kit to its first holder."""
    comparison = coordinated(request, code)
    kit = _kit(comparison, pk)
    try:
        kits.handover_dispatch(kit=kit, from_slot=None, user=request.user,
                               carrier_note=request.POST.get("carrier_note", ""))  # fmt: skip
    except ApplicationError as exc:
        return _refused(request, comparison, kit, exc)
    messages.success(request, f"{kit.name} is logged as sent to its first holder.")
    return redirect("coordinator:kits", code=code)


@login_required
@require_POST
def kit_returned(request: AuthenticatedHttpRequest, code: str, pk: int) -> HttpResponse:
    """The provider logs the kit's return after its last slot."""
    comparison = coordinated(request, code)
    kit = _kit(comparison, pk)
    back = Handover.objects.filter(kit=kit, to_slot__isnull=True, from_slot__isnull=False).first()
    if back is None:
        raise Http404(f"{kit.name} has not been sent back yet.")
    try:
        kits.handover_receive(handover=back, user=request.user,
                              condition=request.POST.get("condition", ""),
                              note=request.POST.get("condition_note", ""))  # fmt: skip
    except ApplicationError as exc:
        return _refused(request, comparison, kit, exc)
    messages.success(request, f"The return of {kit.name} is logged.")
    return redirect("coordinator:kits", code=code)


@login_required
@require_POST
def kit_measurements(request: AuthenticatedHttpRequest, code: str, pk: int) -> HttpResponse:
    """Replace the measurements of a kit (CSV): the pilot's repeats, from which its drift
    is judged, and the linking laboratories' (docs/domain.md §14, §15)."""
    comparison = coordinated(request, code)
    kit = _kit(comparison, pk)
    text = request.POST.get("measurements", "")
    try:
        if len(text) > 10_000_000:
            raise ValidationFailed("Paste at most 10 MB of measurements.")
        n = kits.kit_measurements_replace(kit=kit, text=text)
    except ApplicationError as exc:
        return _refused(request, comparison, kit, exc)
    messages.success(request, f"{n} measurement{'s' if n != 1 else ''} of {kit.name} stored.")
    return redirect("coordinator:kits", code=code)
