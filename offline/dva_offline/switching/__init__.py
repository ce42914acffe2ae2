"""`dva switching`: design the per-sample switching c2 law of the damper, fly it against the best
constant c2 on paired seeds, plot it (docs/switching.md)."""
