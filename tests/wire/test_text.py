"""cdus.wire.text: wire text is escaped and bounded before it is printed."""

from hypothesis import given, strategies as st

from cdus.wire.text import printable


def test_ansi_and_newlines_are_escaped():
    s = printable("ok\x1b[2J\r\nfake line\x07")
    assert "\x1b" not in s and "\n" not in s and "\r" not in s and "\x07" not in s
    assert s == "ok\\x1b[2J\\r\\nfake line\\x07"


def test_bidi_override_escaped_and_plain_unicode_kept():
    assert printable("a\u202eb") == "a\\u202eb"
    assert printable("ω̇ Φ °") == "ω̇ Φ °"


def test_cut_to_limit():
    s = printable("x" * 1000, limit=10)
    assert s == "x" * 10 + "…"


def test_non_string_shown_by_repr():
    assert printable(b"\x1b") == "b'\\x1b'"


@given(st.text(max_size=400), st.integers(min_value=1, max_value=500))
def test_never_a_control_character(text, limit):
    s = printable(text, limit)
    assert len(s) <= limit + 1
    assert not any(ord(c) < 0x20 or 0x7f <= ord(c) < 0xa0 or c in "\u2028\u2029\u202e" for c in s)
