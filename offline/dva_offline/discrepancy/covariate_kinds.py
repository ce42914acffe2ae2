"""What a condition covariate measures, from its column name: an excitation level or not.

A shift of the modes with the excitation level (force, voltage, acceleration, amplitude) is an
amplitude dependence of the structure (a nonlinearity); a shift with a temperature, a pressure
or a humidity is a change of the linear structure (``covariate_shift``). Only the column name
tells them apart; a name that says neither is treated as "the like" of a temperature.
"""
from __future__ import annotations

import re

# words of an excitation level in instrument exports (any case, split at _, -, space, digits)
LEVEL_WORDS = ("force", "level", "amplitude", "ampl", "amp", "voltage", "volt", "excitation",
               "exc", "drive", "current", "rms", "load", "input", "acceleration", "accel",
               "displacement", "disp", "velocity", "vel", "shaker", "hammer", "peak")
# unit suffixes of a level: N, kN, V, mV, A, g, m/s^2 spelled as a name suffix
LEVEL_UNITS = ("n", "kn", "v", "mv", "a", "ma", "g", "ms2", "mm")


def is_level(name: str) -> bool:
    """True when the covariate's name says it is an excitation level (``excitation_n``,
    ``force_rms``, ``Voltage [V]``, ``amp_g``), False otherwise (``temperature_c``)."""
    words = [w for w in re.split(r"[^a-z]+", name.lower()) if w]
    if not words:
        return False
    if any(w in LEVEL_WORDS for w in words):
        return True
    return len(words) > 1 and words[-1] in LEVEL_UNITS and not words[0].startswith("temp")
