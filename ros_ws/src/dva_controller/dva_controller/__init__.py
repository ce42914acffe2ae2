"""Spectrum analysis and semi-active damper controllers for the tunable Maxwell DVA."""
