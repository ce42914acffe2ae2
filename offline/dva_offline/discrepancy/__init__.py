"""Model-discrepancy engine: baseline fit -> held-out error -> residual -> named missing effect.

:mod:`.engine` is domain independent; a domain (:mod:`.frf_domain` for isolator FRFs,
:mod:`.flight_domain` for flight logs) supplies the data, the baseline model, the candidate
library and its residual features. :mod:`.synthetic` and :mod:`.flight_synthetic` generate
test data with one hidden effect and are not used by the engine.
Pure numerics; file access only in the CLI (through :mod:`dva_offline.isolator.isolator_io`).
"""
