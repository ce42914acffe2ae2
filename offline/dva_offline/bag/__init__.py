"""dva bag: inspect and recover rosbag2 MCAP bags."""
