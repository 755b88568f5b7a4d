"""Serializer output from ``values_list`` rows, for the API's hot read paths.

A DRF ``ModelSerializer`` builds its fields anew for every request and reads every
value through model instances (three per result row of a submission: the result, its
measurement point and the device). :class:`ValuesRendering` asks the database for the
serializer's sources as plain columns instead and converts each value with the
serializer's own field (``field.to_representation``), so the answer is the one the
serializer gives: same keys in the same order, same values, ``None`` for NULL
(bench/README.md, "Load test").

Only flat serializers whose sources are model columns reached through non-null foreign
keys qualify (checked when the plan is built, so a serializer that changes into
something else fails loudly, not silently); a ``SerializerMethodField`` must be given
the name of an annotation on the queryset that carries its value.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable, Mapping
from typing import Any

from django.core.exceptions import FieldDoesNotExist, ImproperlyConfigured
from django.db import models
from django.db.models import QuerySet
from django.utils.encoding import is_protected_type
from rest_framework import serializers


class ValuesRendering:
    """``serializer_class(rows, many=True).data``, computed from ``values_list`` rows."""

    def __init__(
        self,
        serializer_class: type[serializers.ModelSerializer],
        *,
        annotations: Mapping[str, str] | None = None,
        computed: Iterable[str] = (),
    ) -> None:
        self.serializer_class = serializer_class
        self.annotations = dict(annotations or {})
        self.computed = frozenset(computed)
        self._plan: tuple[tuple[str, ...], tuple[str, ...], tuple[Any, ...]] | None = None
        self._lock = threading.Lock()

    # -- the plan: (names, lookups, fields), built once per process -------------------------

    def plan(self) -> tuple[tuple[str, ...], tuple[str, ...], tuple[Any, ...]]:
        if self._plan is None:
            with self._lock:
                if self._plan is None:
                    self._plan = self._build_plan()
        return self._plan

    def _build_plan(self) -> tuple[tuple[str, ...], tuple[str, ...], tuple[Any, ...]]:
        serializer = self.serializer_class()
        model = serializer.Meta.model
        names: list[str] = []
        lookups: list[str] = []
        fields: list[Any] = []
        for name, field in serializer.fields.items():
            if field.write_only:
                continue
            if name in self.computed:  # given by the caller to instance()
                names.append(name)
                lookups.append("")
                fields.append(_COMPUTED)
                continue
            if isinstance(field, serializers.SerializerMethodField):
                if name not in self.annotations:
                    raise ImproperlyConfigured(
                        f"{self.serializer_class.__name__}.{name} is a method field: "
                        "give the annotation that carries its value"
                    )
                names.append(name)
                lookups.append(self.annotations[name])
                fields.append(None)  # the annotated value as it is
                continue
            if isinstance(field, serializers.BaseSerializer | serializers.RelatedField):
                raise ImproperlyConfigured(f"{name}: nested and related fields are not flat")
            if isinstance(field, serializers.ModelField):
                # DRF's fallback for model fields it has no class for (a GeneratedField):
                # the column's value as it is, when it is a "protected" type
                lookups.append(_lookup(model, [field.model_field.name], name))
                names.append(name)
                fields.append(_PROTECTED)
                continue
            lookups.append(_lookup(model, field.source_attrs, name))
            names.append(name)
            fields.append(field)
        return tuple(names), tuple(lookups), tuple(fields)

    # -- rendering ---------------------------------------------------------------------------

    def instance(self, obj: models.Model, **computed: Any) -> dict[str, Any]:
        """One object already in memory (columns read from it), ``computed`` fields given."""
        names, lookups, fields = self.plan()
        out: dict[str, Any] = {}
        for name, lookup, field in zip(names, lookups, fields, strict=True):
            if field is _COMPUTED:
                out[name] = computed[name]
                continue
            value: Any = obj
            for attr in lookup.split("__"):
                value = getattr(value, attr)
            out[name] = value if value is None or field is None else field.to_representation(value)
        return out

    def rows(self, queryset: QuerySet[Any]) -> QuerySet[Any]:
        """The queryset's rows as tuples of the serializer's sources (paginate these)."""
        return queryset.values_list(*self.plan()[1])

    def render(self, rows: Iterable[tuple[Any, ...]]) -> list[dict[str, Any]]:
        names, _, fields = self.plan()
        if _COMPUTED in fields:
            raise ImproperlyConfigured("computed fields are for instance() only")
        pairs = tuple(zip(names, map(_converter, fields), strict=True))
        return [
            {
                name: value if value is None or convert is None else convert(value)
                for (name, convert), value in zip(pairs, row, strict=True)
            }
            for row in rows
        ]

    def data(self, queryset: QuerySet[Any]) -> list[dict[str, Any]]:
        return self.render(self.rows(queryset))


class _Protected:
    """``ModelField.to_representation`` for a value of a protected type: the value itself."""

    def to_representation(self, value: Any) -> Any:
        if not is_protected_type(value):
            raise TypeError(f"{type(value).__name__} needs the model instance to render")
        return value


_PROTECTED = _Protected()

#: DRF fields whose ``to_representation`` is exactly a builtin conversion
_BUILTIN = {
    serializers.CharField.to_representation: str,
    serializers.FloatField.to_representation: float,
    serializers.IntegerField.to_representation: int,
}


def _converter(field: Any) -> Any:
    """``field.to_representation``, or the builtin it amounts to (``str(value)`` for a
    ``CharField`` whose class does not override it, and so on); ``None``: as it is."""
    if field is None:
        return None
    return _BUILTIN.get(type(field).to_representation, field.to_representation)


_COMPUTED = _Protected()  # a marker: the caller gives the value


def _lookup(model: type[models.Model], attrs: list[str], name: str) -> str:
    """``["measurement_point", "device", "name"]`` -> ``measurement_point__device__name``,
    refusing paths that are not columns or that cross a nullable relation (where the
    serializer would not answer ``None`` the way a NULL column does)."""
    if not attrs:
        raise ImproperlyConfigured(f"{name}: source='*' is not a column")
    current = model
    for i, attr in enumerate(attrs):
        try:
            model_field: Any = current._meta.get_field(attr)
        except FieldDoesNotExist:
            raise ImproperlyConfigured(f"{name}: {attr!r} is not a field of {current}") from None
        last = i == len(attrs) - 1
        if last:
            if model_field.is_relation:
                raise ImproperlyConfigured(f"{name}: {attr!r} is a relation, not a column")
        else:
            if not (model_field.many_to_one or model_field.one_to_one) or model_field.null:
                raise ImproperlyConfigured(f"{name}: {attr!r} is not a non-null foreign key")
            current = model_field.related_model
    return "__".join(attrs)
