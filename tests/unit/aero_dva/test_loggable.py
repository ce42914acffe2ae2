"""Outside text reaches a log line escaped and cut to a bounded length."""
from __future__ import annotations

from aero_dva.text_input import MAX_LOGGED_CHARS, loggable


def test_control_characters_are_escaped_and_long_text_is_cut():
    assert loggable("switching") == "switching"
    assert loggable("a\nb\x1b[31mc\td") == "a\\nb\\x1b[31mc\\td"
    text = loggable("x" * 10_000_000)
    assert len(text) < MAX_LOGGED_CHARS + 40 and text.endswith("(9,999,880 more characters)")
    assert "\n" not in loggable("\n" * 500) and loggable("ünï ✈") == "ünï ✈"
