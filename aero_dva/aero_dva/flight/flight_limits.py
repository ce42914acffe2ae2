"""The limits every flight, scenario and training plan is held to, and the damper's defaults
(pure constants, no imports but the package root's ranges, so that ``dva --help``, a node's
``--help`` and the controller table can state them without loading the numerics; the modules
that use them re-export them).

Past them a scenario or plan is refused at the door, in one line (exit code 2); the memory a
flight takes per sample on each route is in docs/reliability.md.
"""

# [N s/m] the largest c2 a parameter or a file may hold: its home is the ranges of every input
from aero_dva.input_ranges import MAX_DAMPING as MAX_DAMPING

#: [samples] most a flight may have (duration x sample rate): 20,000,000, 5.6 h at 1 kHz (the
#: study's training sweep has 6.84 million, the default training plan 10.26 million).
MAX_FLIGHT_SAMPLES = 20_000_000
#: [Hz] sample rates a flight may have: below 100 Hz the wing's modes (up to about 30 Hz with
#: the DVA) and the 5-20 Hz spectra are not sampled; above 20 kHz nothing is gained.
SAMPLE_RATE_RANGE = (100.0, 20_000.0)
#: Most samples in one published block (a second at the highest rate).
MAX_BLOCK_SIZE = 20_000
#: [N] largest standard deviation of the aileron force (the study's is 1 kN).
MAX_FORCE_STD = 1.0e6
#: [samples] longest window (dwell) of a training plan: 10 minutes at 1 kHz (the study's: 2 s).
MAX_WINDOW_SAMPLES = 600_000
#: [kg/m^3] air densities a flight may have (40 km altitude to a cold sea-level day).
DENSITY_RANGE = (1e-3, 2.0)

#: [N s/m] the damper's default range of c2 (the simulator's, and the controllers' clamp).
DAMPER_RANGE = (0.0, 2500.0)
#: [s] sim time without an accepted command before the damper falls back (the simulator's
#: default).
DEFAULT_STALE_TIMEOUT = 0.5
#: ``DamperCommand.source`` that asks for the per-sample switching law (its table entry's
#: source).
SWITCHING_SOURCE = "switching"
