"""The API's request parsers: DRF's, refusing control characters in what they parse.

A JSON string (a value or a key) or a form field with a C0 control character other than
tab, LF and CR is a 400 naming its place (``results[3].note``), in the error shape of
docs/interfaces.md §3, instead of a database error (PostgreSQL refuses NUL in text).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from rest_framework import parsers

from common.middleware import ControlCharacters, check_query_dict, control_message


def json_errors(data: Any, path: str = "") -> Iterator[dict[str, Any]]:
    """Error rows for every string of a parsed JSON document with a control character."""
    if isinstance(data, str):
        if why := control_message(data):
            yield {"field": path or None, "message": f"The value {why}."}
    elif isinstance(data, dict):
        for key, value in data.items():
            if why := control_message(key):
                escaped = key.encode("unicode_escape").decode()
                yield {"field": path or None, "message": f"The key '{escaped}' {why}."}
            else:
                yield from json_errors(value, f"{path}.{key}" if path else key)
    elif isinstance(data, list):
        for index, value in enumerate(data):
            yield from json_errors(value, f"{path}[{index}]")


class JSONParser(parsers.JSONParser):
    """A view may name top-level keys whose content it validates itself, cell by cell,
    naming row and column (``validates_control_characters = ("results",)``: the results
    rows go through the importer, which refuses control characters in every cell)."""

    def parse(self, stream: Any, media_type: Any = None, parser_context: Any = None) -> Any:
        data = super().parse(stream, media_type, parser_context)
        view = (parser_context or {}).get("view")
        own = set(getattr(view, "validates_control_characters", ()) or ())
        checked = (
            {k: v for k, v in data.items() if k not in own}
            if own and isinstance(data, dict)
            else data
        )
        if errors := list(json_errors(checked)):
            raise ControlCharacters(errors)
        return data


class FormParser(parsers.FormParser):
    def parse(self, stream: Any, media_type: Any = None, parser_context: Any = None) -> Any:
        data = super().parse(stream, media_type, parser_context)
        check_query_dict(data)
        return data


class MultiPartParser(parsers.MultiPartParser):
    """The text fields (Django already removes unprintable characters from file names)."""

    def parse(self, stream: Any, media_type: Any = None, parser_context: Any = None) -> Any:
        result = super().parse(stream, media_type, parser_context)
        check_query_dict(result.data)
        return result
