"""The names of the wing's outputs, in their order (pure constants, no imports: the controller
table and a node's ``--help`` state them without loading the numerics; the model re-exports
them)."""

#: Displacement outputs: plunge [m], pitch [rad], leading edge [m], absorber stroke [m].
DISPLACEMENT_NAMES = ("plunge", "pitch", "leading_edge", "absorber_stroke")
#: Acceleration outputs: plunge [m/s^2], pitch [rad/s^2], leading edge [m/s^2].
ACCELERATION_NAMES = ("plunge", "pitch", "leading_edge")
