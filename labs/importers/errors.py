"""Row errors of the results-table importer (docs/interfaces.md §1 and §3).

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
        """The shape of one entry of the API's ``errors`` list (docs/interfaces.md §3)."""
        return {"row": self.row, "field": self.field, "message": self.message}

    def __str__(self) -> str:
        where = []
        if self.row is not None:
            where.append(f"row {self.row}")
        if self.field is not None:
            where.append(f"column {self.field}")
        return f"{', '.join(where)}: {self.message}" if where else self.message


#: Every listing of problems (API, web pages, commands) stops here, with a count of the rest.
MAX_LISTED_ERRORS = 1_000


class ImportErrors(Exception):
    """The table was rejected; ``errors`` lists the first :data:`MAX_LISTED_ERRORS` problems
    found (in row order) and ``total`` counts all of them."""

    def __init__(self, errors: Iterable[RowError], total: int | None = None) -> None:
        found = list(errors)
        self.total: int = max(len(found), total or 0)
        self.errors: list[RowError] = found[:MAX_LISTED_ERRORS]
        super().__init__(self.errors)

    @property
    def more(self) -> int:
        """How many problems are counted but not listed."""
        return self.total - len(self.errors)

    def more_line(self) -> str | None:
        """``... and 2,599,000 more problems`` when some are not listed."""
        return more_problems(self.more)

    def __str__(self) -> str:
        lines = [str(error) for error in self.errors]
        more = self.more_line()
        return "\n".join([*lines, more] if more else lines)

    def as_dicts(self) -> list[dict[str, int | str | None]]:
        """The listed problems, then an entry without row or field counting the rest."""
        listed = [error.as_dict() for error in self.errors]
        more = self.more_line()
        return [*listed, {"row": None, "field": None, "message": more}] if more else listed


def more_problems(n: int) -> str | None:
    return f"... and {n:,} more problem{'s' if n != 1 else ''}" if n > 0 else None


def fatal(message: str, *, row: int | None = None, field: str | None = None) -> ImportErrors:
    """An :class:`ImportErrors` for a problem that stops parsing at once."""
    return ImportErrors([RowError(row, field, message)])
