"""A two-sensor bag written the way a recorder writes one, for the ``tcomp process`` benchmarks.

``ros2 bag record`` (and rosbags' :class:`~rosbags.rosbag2.Writer`, which this module uses)
writes each message as it arrives: the two sensors' messages interleaved one by one, in
uncompressed chunks closed at 1 MB. That is the layout a new user hands to ``tcomp process``,
and it differs from the bulk writer of ``bench_process.make_bag`` (one block of a sensor's
messages after the other, zstd chunks): every chunk holds about 13 000 short runs of one
message per topic.

The signal is ``bench_process``'s (:func:`bench_process.sensor_blocks`: a 10 Hz and a 1 Hz
sinusoid about 300 °C through the paper's two lags, σ = 0.3 °C of noise on each reading).
Payloads are encoded with :func:`tcomp_core.io.encode` (byte-identical to rosbags'
``serialize_cdr``, and faster).
"""

from __future__ import annotations

from bench_process import sensor_blocks

from tcomp_core.io import DEFAULT_TOPICS, TEMPERATURE_TYPE, encode, offered_qos

__all__ = ["recorder_bag"]


def recorder_bag(path, minutes: float, rate_hz: int, seed: int = 7):
    """Write the bag at ``path`` (a directory that must not exist) and return it.

    Parameters
    ----------
    path : Path
        The bag directory to create.
    minutes : float
        Length of the record, minutes.
    rate_hz : int
        Sample rate of each sensor, Hz; ``minutes * 60 * rate_hz`` pairs.
    seed : int
        Seed of the noise generator.

    Returns
    -------
    Path
        ``path``.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_JAZZY)
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connections = [
            writer.add_connection(
                topic, TEMPERATURE_TYPE, typestore=typestore, offered_qos_profiles=offered_qos()
            )
            for topic in DEFAULT_TOPICS[:2]
        ]
        for stamps, readings in sensor_blocks(minutes, rate_hz, seed):
            first, second = (encode(stamps, values, 0.0, "probe") for values in readings)
            for row, stamp in enumerate(stamps.tolist()):
                writer.write(connections[0], stamp, first[row].tobytes())
                writer.write(connections[1], stamp, second[row].tobytes())
    return path
