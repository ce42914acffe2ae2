"""dva evaluate: paired closed-loop flights in one process, or flights through the ROS 2 graph."""
