"""The project's Fast DDS profile: reliable writers send a heartbeat every 50 ms, not every 3 s.

A reliable reader acknowledges what it holds when the writer's heartbeat asks, so
``wait_for_all_acked`` (the simulator and the bag player wait for their readers before they
exit: nothing sent is lost when a loaded reader is behind) lasted until the next heartbeat,
up to Fast DDS's default period of 3 s, after every flight; a lost sample is also repaired on
a heartbeat. At 50 ms the wait is what the readers need (docs/performance.md, issue 43). Only
the heartbeat changes: every ROS QoS comes from the node as before.

:func:`use_dds_profile` points ``FASTRTPS_DEFAULT_PROFILES_FILE`` at the profile in this
process's environment, before its first DDS participant (the nodes a run starts inherit it).
A profile file the user set is kept, and then its heartbeat holds.
"""
from __future__ import annotations

import os
from pathlib import Path

__all__ = ["ENV_PROFILE", "PROFILE", "use_dds_profile"]

ENV_PROFILE = "FASTRTPS_DEFAULT_PROFILES_FILE"
PROFILE = Path(__file__).with_name("fastdds_profile.xml")


def use_dds_profile() -> str:
    """Set :data:`ENV_PROFILE` to :data:`PROFILE` unless the environment names a file already;
    return the file in use. Read by Fast DDS when the process creates its first participant."""
    own = os.environ.get(ENV_PROFILE)
    if own:
        return own
    os.environ[ENV_PROFILE] = str(PROFILE)
    return str(PROFILE)
