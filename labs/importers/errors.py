"""Row errors of the results-table importer (formats.md §1 and §3).

A table that does not fit is rejected whole: the importer collects every problem
as a :class:`RowError` and raises one :class:`ImportErrors` carrying all of them.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class RowError:
    """One problem in one row and column.

    ``row`` is the row number a spreadsheet user sees (header = row 1), or the
    1-based index of a JSON result; ``None`` for a problem with the whole file.
    ``field`` is the column name, or ``None`` when no single column is at fault.
    """

    row: int | None
    field: str | None
    message: str

    def as_dict(self) -> dict[str, int | str | None]:
        """The shape of one entry of the API's ``errors`` list (formats.md §3)."""
        return {"row": self.row, "field": self.field, "message": self.message}

    def __str__(self) -> str:
        where = []
        if self.row is not None:
            where.append(f"row {self.row}")
        if self.field is not None:
            where.append(f"column {self.field}")
        return f"{', '.join(where)}: {self.message}" if where else self.message


class ImportErrors(Exception):
    """The table was rejected; ``errors`` lists every problem found."""

    def __init__(self, errors: Iterable[RowError]) -> None:
        self.errors: list[RowError] = list(errors)
        super().__init__(self.errors)

    def __str__(self) -> str:
        return "\n".join(str(error) for error in self.errors)

    def as_dicts(self) -> list[dict[str, int | str | None]]:
        return [error.as_dict() for error in self.errors]


def fatal(message: str, *, row: int | None = None, field: str | None = None) -> ImportErrors:
    """An :class:`ImportErrors` for a problem that stops parsing at once."""
    return ImportErrors([RowError(row, field, message)])
