"""dva control: the optimal c2, the airspeed schedule and their plots."""
