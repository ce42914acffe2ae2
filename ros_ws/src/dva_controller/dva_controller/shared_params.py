"""Parameter rows of the controller table as node parameters: a law's own rows (the controller
and supervisor nodes declare them), and the spectra's shape, which the spectrum node shares with
a law of spectra (it makes them, the law checks it reads what it was made for)."""
from __future__ import annotations

import dataclasses

from aero_dva.control import controllers as table
from dva_ros_common.node_params import Param

__all__ = ["SPECTRUM_SHAPE", "param"]


def param(row: table.LawParam) -> Param:
    """A law's parameter as a row of a node's table."""
    return Param(**dataclasses.asdict(row))


#: channels, frequencies, window, window_duration of the eq. 7.3 spectra.
SPECTRUM_SHAPE = tuple(param(row) for row in table.SPECTRUM_SHAPE)
