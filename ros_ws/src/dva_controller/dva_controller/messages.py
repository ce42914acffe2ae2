"""Conversions between dva_msgs messages and plain Python values (the only module of this package
that builds or reads messages, so the nodes stay thin and the numerics stay ROS-free)."""
from __future__ import annotations

from builtin_interfaces.msg import Time

from dva_msgs.msg import DamperCommand


def damper_command(stamp: Time, damping: float, source: str) -> DamperCommand:
    """A ``dva_msgs/DamperCommand`` for c2 = ``damping`` [N s/m] from controller ``source``."""
    msg = DamperCommand()
    msg.header.stamp = stamp
    msg.damping = float(damping)
    msg.source = source
    return msg
