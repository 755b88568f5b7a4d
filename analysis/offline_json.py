"""The JSON of ``pt_compare`` (docs/interfaces.md §4), written a chunk of results at a time.

Compact by default: the score records are joined from column pieces that orjson writes
(:func:`score_json_chunks`), byte for byte ``orjson.dumps`` of the records without a
dictionary per result. ``indent``: laid out as ``json.dumps(indent=...)`` does, from
orjson's two-space layout. NaN and infinity are written as null.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Iterator
from itertools import repeat
from typing import Any

import numpy as np
import orjson

from analysis.consistency import iter_records
from analysis.pipeline import (
    SIGMA_KEYS,
    Analysis,
    score_columns,
    score_record_chunks,
    to_json,
)
from common.points import POINT_FIELDS

CHUNK = 20_000  # results per chunk of output
_JSON = orjson.OPT_SERIALIZE_NUMPY  # NaN and inf are written as null


def json_parts(analysis: Analysis, indent: int | None = None) -> Iterator[bytes]:
    """The document of docs/interfaces.md §4 (``to_json``'s keys, in order), the scores a chunk at a
    time; compact, or indented by ``indent`` spaces as ``json.dumps(indent=...)`` lays it out."""
    doc = to_json(analysis, scores=False)
    parts = _json_indented(doc, analysis) if indent is not None else _json_compact(doc, analysis)
    if indent is None or indent == 2:
        yield from parts
        return
    for part in parts:  # orjson indents by two; strings hold no raw line break
        yield _INDENT.sub(lambda m: b"\n" + b" " * (len(m.group(1)) // 2 * indent), part)


_INDENT = re.compile(rb"\n( *)")


def _json_compact(doc: dict[str, Any], analysis: Analysis) -> Iterator[bytes]:
    yield b"{"
    for n, (key, value) in enumerate(doc.items()):
        yield (b"," if n else b"") + orjson.dumps(key) + b":"
        if key == "consistency":
            yield from _consistency_json(analysis, _JSON, b"", b"")
            continue
        if key != "scores":
            yield orjson.dumps(value, option=_JSON)
            continue
        yield b"["
        for i, chunk in enumerate(score_json_chunks(analysis, CHUNK)):
            yield b"," + chunk if i else chunk
        yield b"]"
    yield b"}\n"


def _consistency_json(
    analysis: Analysis, option: int, before: bytes, end: bytes
) -> Iterator[bytes]:
    """The ``consistency`` list a point at a time (a record holds an entry per result of
    its point): ``orjson.dumps`` of the whole list, compact (``before`` and ``end`` empty)
    or indented as the document's other keys are (a record is two levels deep)."""
    records = iter_records(analysis)
    first = next(records, None)
    if first is None:
        yield b"[]"
        return
    for i, rec in enumerate(itertools.chain([first], records)):
        body = orjson.dumps(rec, option=option)
        yield (
            (b"[" if i == 0 else b",") + before + (body.replace(b"\n", before) if before else body)
        )
    yield end + b"]"


def score_json_chunks(analysis: Analysis, size: int) -> Iterator[bytes]:
    """The score records as compact JSON, ``size`` records at a time, comma-separated: the
    bytes of ``orjson.dumps(records)[1:-1]`` without a dictionary per result.

    Each column's values are written by orjson a chunk at a time (a float array in one
    call; text once per distinct value), the point's keys once per measurement point (the
    results were grouped by exactly those values), then the records are joined from the
    pieces."""
    columns, has_sigma = score_columns(analysis)
    index = analysis.groups.index
    heads = np.array(
        [b"{" + b",".join(_pair(k, v) for k, v in zip(POINT_FIELDS, p, strict=True))
         for p in analysis.points],
        dtype=object,
    )  # fmt: skip
    rest = [k for k in columns if k not in POINT_FIELDS]
    prefixes = {k: b"," + orjson.dumps(k) + b":" for k in rest}
    memo: dict[str, dict[Any, bytes]] = {k: {} for k in rest}
    for start in range(0, has_sigma.size, size):
        rows = slice(start, start + size)
        sigma = has_sigma[rows]
        parts: list[Any] = [heads[index[rows]].tolist()]
        for k in rest:
            if k in SIGMA_KEYS and not sigma.all():
                if sigma.any():  # the key only in the records whose point has a σ_pt
                    values = _fragments(columns[k][rows], memo[k])
                    has = sigma.tolist()
                    parts.append(
                        [prefixes[k] + v if h else b"" for v, h in zip(values, has, strict=True)]
                    )
                continue
            parts += [repeat(prefixes[k]), _fragments(columns[k][rows], memo[k])]
        parts.append(repeat(b"}"))
        yield b",".join(map(b"".join, zip(*parts, strict=False)))  # repeat() is endless


def _pair(key: str, value: Any) -> bytes:
    return orjson.dumps(key) + b":" + orjson.dumps(value, option=_JSON)


_BOOLS = (b"false", b"true")


def _fragments(values: np.ndarray, memo: dict[Any, bytes]) -> list[bytes]:
    """Each value's JSON text. Object columns hold text, booleans and None only (no number
    that a dictionary would take for a boolean)."""
    if values.dtype.kind == "f":
        return orjson.dumps(np.ascontiguousarray(values), option=_JSON)[1:-1].split(b",")
    if values.dtype.kind == "b":
        return list(map(_BOOLS.__getitem__, values.tolist()))
    items = values.tolist()
    for v in dict.fromkeys(items):
        if v not in memo:
            memo[v] = orjson.dumps(v)
    return list(map(memo.__getitem__, items))


def _json_indented(doc: dict[str, Any], analysis: Analysis) -> Iterator[bytes]:
    indented = _JSON | orjson.OPT_INDENT_2
    yield b"{"
    for n, (key, value) in enumerate(doc.items()):
        yield (b",\n  " if n else b"\n  ") + orjson.dumps(key) + b": "
        if key == "consistency":
            yield from _consistency_json(analysis, indented, b"\n    ", b"\n  ")
            continue
        if key != "scores" or not analysis.table.value.size:
            yield orjson.dumps(value, option=indented).replace(b"\n", b"\n  ")
            continue
        yield b"["
        for i, chunk in enumerate(score_record_chunks(analysis, CHUNK)):
            body = orjson.dumps(chunk, option=indented)[2:-2]  # without "[\n" and "\n]"
            yield (b"," if i else b"") + b"\n  " + body.replace(b"\n", b"\n  ")
        yield b"\n  ]"
    yield b"\n}\n"
