"""Aeroelastic wing with a tunable Maxwell-element DVA: pure model code and ROS 2 nodes."""
