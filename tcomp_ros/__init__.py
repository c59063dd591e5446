"""tcomp_ros: thin rclpy nodes around :mod:`tcomp_core` (compensator and replay).

Importing it imports :mod:`tcomp_core` first, which keeps BLAS single-threaded before numpy
loads (see there).
"""

import tcomp_core  # noqa: F401  (before rclpy and numpy)
