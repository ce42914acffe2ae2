"""The exit-code table and the signals (aero_dva.exits)."""
from __future__ import annotations

import os
import signal

import pytest

from aero_dva import exits


def test_one_meaning_per_code_and_the_help_says_each():
    assert set(exits.TABLE) == {0, 1, 2, 3, 130, 141}
    text = exits.help_text()
    for code, meaning in exits.TABLE.items():
        assert f"{code} {meaning}" in text
    assert exits.meaning(-9) == "killed by signal 9"


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_sigint_and_sigterm_raise_the_same_interrupt_naming_the_signal(signum):
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(exits.Interrupted) as raised, exits.signals_interrupt():
        os.kill(os.getpid(), signum)
        for _ in range(10**6):  # the handler runs between two bytecodes, before this ends
            pass
    assert raised.value.signal_name == signal.Signals(signum).name
    assert isinstance(raised.value, KeyboardInterrupt)
    assert signal.getsignal(signal.SIGTERM) == before  # restored


def test_a_failure_while_stopping_on_a_signal_is_still_the_interrupt():
    """A signal lands anywhere; a clean-up it leaves half done may fail in turn (a progress
    bar's lock never made): the command was interrupted, not broken."""
    try:
        try:
            raise exits.Interrupted(signal.SIGTERM)
        finally:
            raise AttributeError("type object 'tqdm' has no attribute '_lock'")
    except AttributeError as exc:
        found = exits.interrupt_in(exc)
    assert isinstance(found, exits.Interrupted) and found.signal_name == "SIGTERM"
    assert exits.interrupt_in(ValueError("plain")) is None
