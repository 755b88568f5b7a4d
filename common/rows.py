"""Whole model rows read with one hand-written SELECT, for per-request lookups.

Two lookups run on every API request of a laboratory: its key (with the laboratory)
and its participation in the comparison named in the URL (with the comparison).
Building them with the ORM costs ≈ 1 ms of CPU each, nearly all of it spent compiling
the same SQL again (bench/README.md, "Load test"). :class:`ModelColumns` writes the
column list of a model once, and turns a row back into an instance the way the ORM
does: every value through Django's own converters for that column on that database
(SQLite dates, PostgreSQL as is), then ``Model.from_db``. The SQL stays ordinary
parametrised SQL, so it is the same query, with the same result, at every request.
"""

from __future__ import annotations

from typing import Any

from django.db import connections, models


class ModelColumns:
    """All concrete columns of ``model`` under the table alias ``alias``."""

    def __init__(self, model: type[models.Model], alias: str) -> None:
        self.model = model
        self.alias = alias
        self.fields = tuple(model._meta.concrete_fields)
        self.attnames = [f.attname for f in self.fields]

    def select(self, using: str) -> str:
        qn = connections[using].ops.quote_name
        return ", ".join(f"{qn(self.alias)}.{qn(f.column)}" for f in self.fields)

    def converters(self, using: str) -> list[tuple[int, Any, list[Any]]]:
        """(position, column expression, converters) of each column that has converters."""
        connection = connections[using]
        out = []
        for i, f in enumerate(self.fields):
            col = f.get_col(self.alias)
            convs = connection.ops.get_db_converters(col) + col.get_db_converters(connection)
            if convs:
                out.append((i, col, convs))
        return out


class JoinedQuery:
    """``SELECT <columns of each part> <rest>``: one instance per part and row.

    ``rest`` is the ``FROM ... WHERE ...`` part with ``%s`` parameters and identifiers in
    double quotes (standard SQL: PostgreSQL and SQLite, the two supported databases)."""

    def __init__(self, parts: list[ModelColumns], rest: str) -> None:
        self.parts = parts
        self.rest = rest
        self._prepared: dict[str, tuple[str, list[Any]]] = {}

    def _prepare(self, using: str) -> tuple[str, list[Any]]:
        prepared = self._prepared.get(using)
        if prepared is None:
            columns = ", ".join(part.select(using) for part in self.parts)
            sql = f"SELECT {columns} {self.rest}"
            prepared = self._prepared[using] = (sql, [p.converters(using) for p in self.parts])
        return prepared

    def fetch(self, params: list[Any], using: str = "default") -> list[list[models.Model]]:
        sql, converters = self._prepare(using)
        connection = connections[using]
        with connection.cursor() as cursor:
            cursor.execute(sql, params)
            rows = cursor.fetchall()
        out = []
        for row in rows:
            instances, start = [], 0
            for part, part_converters in zip(self.parts, converters, strict=True):
                values = list(row[start : start + len(part.fields)])
                start += len(part.fields)
                for i, col, convs in part_converters:
                    for conv in convs:
                        values[i] = conv(values[i], col, connection)
                instances.append(part.model.from_db(using, part.attnames, values))
            out.append(instances)
        return out
