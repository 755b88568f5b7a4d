"""Sizes in the words of an error message (no Django: the importers use it too)."""


def human_size(n_bytes: float) -> str:
    """``6.2 MB``, ``5 MB``, ``12 kB``, ``300 bytes`` (binary multiples)."""
    for size, name in ((2**20, "MB"), (2**10, "kB")):
        if n_bytes >= size:
            return f"{n_bytes / size:.1f}".removesuffix(".0") + f" {name}"
    return f"{int(n_bytes)} bytes"
