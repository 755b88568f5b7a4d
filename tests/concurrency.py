"""Requests made at the same moment, for the tests of races (each thread its own connection)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from django.db import connection


def at_once(*calls: Callable[[], object]) -> list[Any]:
    """Run ``calls`` in threads released together (each thread has its own connection).

    Their answers, or the exceptions they raised (the tests check for those)."""
    barrier = threading.Barrier(len(calls))
    out: list[Any] = [None] * len(calls)

    def body(i: int) -> None:
        try:
            barrier.wait(10)
            out[i] = calls[i]()
        except BaseException as exc:  # reported by the test, not lost in the thread
            out[i] = exc
        finally:
            connection.close()

    threads = [threading.Thread(target=body, args=(i,)) for i in range(len(calls))]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    return out
