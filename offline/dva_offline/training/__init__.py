"""dva train: the training plan, the recorded sweep, and the RBF network fitted to it."""
