"""Rubber isolator models (Voigt, Maxwell-Voigt, general Maxwell) and their identification.

Zhang (2006), chapters 3-5. Pure numerics (no ROS); file access only in :mod:`.files`.
"""
