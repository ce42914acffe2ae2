"""Model discrepancy: baseline fit -> held-out error -> residual -> named missing effect(s).

:mod:`.fitting` (parametric models, multi-start fits) and :mod:`.loop` (scores, verdict, the
step-by-step loop) are domain independent; a domain (:mod:`.frf_domain` for isolator and
viscoelastic FRFs, :mod:`.modal_domain` for structures, :mod:`.flight_domain` for flight logs)
supplies the data, the baseline model, the candidate library and its residual features.
:mod:`.synthetic`, :mod:`.structure_synthetic` and :mod:`.flight_synthetic` generate test data
with hidden effects and are not used by the loop. Pure numerics; file access only in the CLI
(through :mod:`.table_io` and :mod:`dva_offline.isolator.files`).
"""
