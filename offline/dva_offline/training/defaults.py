"""The RBF training's choices that ``dva train rbf --help`` shows (no numerics imported here)."""
from __future__ import annotations

__all__ = ["DEFAULT_SPREADS", "LABEL_METHODS", "MAX_CANDIDATES", "MIN_ACTIVATION"]

#: Candidate spreads in min-max scaled input space (33 inputs: distances of order 0.1 .. 1).
DEFAULT_SPREADS = (0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5, 2.0, 3.0)
#: A network whose median peak activation on its validation inputs is below this has neurons
#: that do not respond to inputs it has not seen: it outputs its bias, a constant c2.
MIN_ACTIVATION = 0.1
#: Candidate centres of the OLS selection at most (evenly spaced through the training windows):
#: the candidate matrix is n_train x n_candidates doubles (8 000 x 2 000 = 128 MB).
MAX_CANDIDATES = 2000
#: How the windows get their c2 labels (``training.labels``).
LABEL_METHODS = ("exact", "measured-argmin")
