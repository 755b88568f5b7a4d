"""Results-table importer: CSV/XLSX/JSON -> validated rows + row errors, no ORM, no Django.

See :mod:`labs.importers.table` for the entry points and docs/interfaces.md §1 for the columns.
"""

from .errors import ImportErrors, RowError
from .schema import (
    COLUMNS,
    REQUIRED_COLUMNS,
    LabColumn,
    PointKey,
    ResultRow,
    TableContext,
    missing_points,
)
from .table import MAX_BYTES, MAX_ROWS, parse_rows, parse_table, write_table, write_table_to

__all__ = [
    "COLUMNS",
    "MAX_BYTES",
    "MAX_ROWS",
    "REQUIRED_COLUMNS",
    "ImportErrors",
    "LabColumn",
    "PointKey",
    "ResultRow",
    "RowError",
    "TableContext",
    "missing_points",
    "parse_rows",
    "parse_table",
    "write_table",
    "write_table_to",
]
