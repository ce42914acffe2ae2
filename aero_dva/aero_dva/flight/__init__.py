"""The flight layer: the wing in time (exact zero-order hold), the damper model, scenarios, the
streaming and batch simulators, the training sweep and the hidden plant for discrepancy tests.
May import: ``aero_dva.wing`` and the package root; never ``control`` or ``bag``.
"""
