"""dva replay: a recorded flight's controller re-run offline, and the comparison."""
