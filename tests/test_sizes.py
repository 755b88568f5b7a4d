"""``common.sizes.database_id``: a row id from text, never an exception."""

from __future__ import annotations

import pytest

from common.sizes import database_id


@pytest.mark.parametrize("text, expected", [
    ("1", 1), ("0042", 42), ("999999999999999999", 999_999_999_999_999_999),
    ("", None), ("²", None), ("１２", None), ("٣", None), ("-1", None), ("+1", None),
    (" 1", None), ("1.0", None), ("1e3", None), ("\x00", None),
    ("9999999999999999999", None),  # 19 digits: may overflow a bigint, never looked up
])  # fmt: skip
def test_plain_ascii_digits_that_fit_a_bigint_only(text, expected):
    assert database_id(text) == expected
