"""ROS glue shared by every node of the project (needs rclpy; the numerics live in aero_dva).

``node_tools``: the executor, how it spins, a node's ``main`` body, bounded parameters, input
health. ``conversions``: ROS time and ``diagnostic_msgs`` builders.
"""
