"""tcomp_ros: thin rclpy nodes around :mod:`tcomp_core` (compensator and replay).

The nodes arrive with the ROS issue; this package already ships the ament index marker,
``package.xml`` and the parameter files so the distribution installs in a colcon workspace.
"""
