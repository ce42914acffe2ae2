"""The flight layer: the wing sampled in time (one discrete model, exact zero-order hold), its
simulators (streaming, batch, parallel-in-time sweep, hidden plant, modal), the damper,
scenarios and the flight runtime; ``per_sample``: the laws that set c2 every sample in the
damper path, with their compiled loops. May import: ``aero_dva.wing`` and the package root;
never ``control`` or ``bag``.
"""
