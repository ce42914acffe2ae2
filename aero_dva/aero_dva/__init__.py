"""The ROS-free domain of aero-dva: the wing with its tunable Maxwell DVA, flights, control and
design maths, and bag (rosbag2/MCAP) files.

Layers, each a folder that imports only the ones below it::

    bag/      rosbag2 MCAP bags: schemas from the .msg files, writers, readers, recorded sweeps
    control/  design and control maths: stationary RMS, optimal c2, DVA design, spectrum, RBF
    flight/   flights in time: the discrete model, simulators, damper, scenarios, sweeps
    wing/     the pitch-plunge wing, aerodynamics, absorbers, flutter, modal analysis, wing files

``bag`` and ``control`` stand side by side above ``flight`` and do not import each other.
``data_files``, ``atomic_io`` and ``text_input`` serve every layer. Nothing here imports rclpy
or dva_msgs.
"""
