"""Every route the project serves, discovered from the URL resolver (nothing listed by hand)."""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from django.urls import URLPattern, URLResolver, get_resolver

#: ``<converter:name>`` or ``<name>`` in a route
PARAM = re.compile(r"<(?:(?P<converter>[^>:]+):)?(?P<name>[^>]+)>")


@dataclass(frozen=True)
class Route:
    """One URL pattern: its full route (the table key), its name and its view callable."""

    route: str
    name: str | None
    callback: Any

    @property
    def params(self) -> list[str]:
        return [m.group("name") for m in PARAM.finditer(self.route)]

    def url(self, values: dict[str, Any]) -> str:
        """The path with each ``<...:name>`` replaced by ``values[name]``."""
        return "/" + PARAM.sub(lambda m: str(values[m.group("name")]), self.route)


def _walk(patterns: list[Any], prefix: str, namespace: str) -> Iterator[Route]:
    for p in patterns:
        if isinstance(p, URLResolver):
            ns = f"{namespace}{p.namespace}:" if p.namespace else namespace
            yield from _walk(p.url_patterns, prefix + str(p.pattern), ns)
        elif isinstance(p, URLPattern):
            name = f"{namespace}{p.name}" if p.name else None
            yield Route(prefix + str(p.pattern), name, p.callback)


def discover() -> list[Route]:
    """All routes of ``ROOT_URLCONF``, recursively through every ``include()``."""
    return list(_walk(get_resolver().url_patterns, "", ""))
