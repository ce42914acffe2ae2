"""Offline tools (no ROS needed) for the aeroelastic wing with a tunable Maxwell-element DVA."""

__version__ = "0.1.0"
