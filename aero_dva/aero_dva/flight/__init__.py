"""The flight layer: the wing sampled in time (one discrete model, exact zero-order hold), its
simulators (streaming, batch, parallel-in-time sweep, hidden plant, modal), the damper,
scenarios and the flight runtime. May import: ``aero_dva.wing`` and the package root; never
``control`` or ``bag``.
"""
