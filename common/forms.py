"""Form helpers shared by the apps' pages."""

from __future__ import annotations

from typing import Any

from django import forms


class BootstrapMixin:
    """Bootstrap 5 classes on every widget (no crispy-forms needed for these small forms)."""

    fields: dict[str, forms.Field]  # the form's, this mixin comes first in its bases

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        for field in self.fields.values():
            widget = field.widget
            if isinstance(widget, forms.CheckboxInput | forms.CheckboxSelectMultiple):
                css = "form-check-input"
            elif isinstance(widget, forms.Select | forms.SelectMultiple):
                css = "form-select"
            else:
                css = "form-control"
            widget.attrs.setdefault("class", css)


class ByName(forms.ModelMultipleChoiceField):
    """Choices labelled by the rows' ``name`` alone (a device within its own round, not
    its ``str()``, which names the round too)."""

    def label_from_instance(self, obj: Any) -> str:
        return str(obj.name)
