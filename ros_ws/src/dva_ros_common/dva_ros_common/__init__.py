"""ROS glue shared by every node of the project (needs rclpy; the numerics live in aero_dva).

``node_tools``: the executor, how it spins, a node's ``main`` body, input health.
``node_params``: a node's parameter table, declared from and printed by ``--help``.
``conversions``: ROS time and ``diagnostic_msgs`` builders.
"""
