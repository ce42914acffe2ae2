"""The design and control maths: exact stationary RMS, optimal damping c2*, DVA design studies,
the scaled spectrum (eq. 7.3), the RBF network and the airspeed schedule, with their files.
May import: ``aero_dva.flight``, ``aero_dva.wing`` and the package root; never ``bag``.
"""
