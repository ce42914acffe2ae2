"""The wing layer: the pitch-plunge wing with a passive or tunable Maxwell DVA (Zhang (2006)
eq. 6.1-6.16), aerodynamics, flutter and modal analysis, and the wing files.
May import: numpy, scipy, yaml, ``aero_dva.data_files`` and ``aero_dva.text_input``; never
another layer.
"""
