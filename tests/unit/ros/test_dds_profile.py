"""The project's Fast DDS profile (dva_ros_common.dds_profile): what it sets and when it keeps
the user's."""
from __future__ import annotations

import xml.etree.ElementTree as ET

from dva_ros_common import dds_profile
from dva_ros_common.dds_profile import ENV_PROFILE, PROFILE, use_dds_profile

NS = {"f": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}


def test_the_profile_is_the_default_writer_with_a_50_ms_heartbeat_and_nothing_else():
    root = ET.parse(PROFILE).getroot()
    writers = root.findall("f:data_writer", NS)
    assert len(writers) == 1 and writers[0].get("is_default_profile") == "true"
    period = writers[0].find("f:times/f:heartbeatPeriod", NS)
    assert int(period.find("f:sec", NS).text) == 0
    assert int(period.find("f:nanosec", NS).text) == 50_000_000
    # only the heartbeat: every ROS QoS (reliability, history, durability) stays the node's
    assert [child.tag.split("}")[1] for child in writers[0]] == ["times"]
    assert [child.tag.split("}")[1] for child in root] == ["data_writer"]


def test_it_is_set_when_unset_and_a_users_profile_is_kept(monkeypatch):
    monkeypatch.delenv(ENV_PROFILE, raising=False)
    assert use_dds_profile() == str(PROFILE)
    assert dds_profile.os.environ[ENV_PROFILE] == str(PROFILE)
    monkeypatch.setenv(ENV_PROFILE, "/etc/my_profiles.xml")
    assert use_dds_profile() == "/etc/my_profiles.xml"
    assert dds_profile.os.environ[ENV_PROFILE] == "/etc/my_profiles.xml"
