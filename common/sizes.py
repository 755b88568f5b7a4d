"""Sizes and counts in the words of a message (no Django: the pure cores use it too)."""


def human_size(n_bytes: float) -> str:
    """``6.2 MB``, ``5 MB``, ``12 kB``, ``300 bytes`` (binary multiples)."""
    for size, name in ((2**20, "MB"), (2**10, "kB")):
        if n_bytes >= size:
            return f"{n_bytes / size:.1f}".removesuffix(".0") + f" {name}"
    return f"{int(n_bytes)} bytes"


def counted(n: int, noun: str, plural: str | None = None) -> str:
    """``1 measurement point``, ``3 measurement points``, ``2 laboratories`` (with
    ``plural``): a count and its noun, never "point(s)"."""
    return f"{n} {noun if n == 1 else plural or noun + 's'}"


def database_id(text: str) -> int | None:
    """``text`` as a row id when it is plain ASCII digits that fit a bigint, else None:
    ``"²".isdigit()`` is True in Python but ``int("²")`` fails, and 20 digits overflow
    PostgreSQL's bigint."""
    if not (text.isascii() and text.isdigit()) or len(text) > 18:
        return None
    return int(text)
