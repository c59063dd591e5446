"""The QoS offered for written topics, in the forms rosbags and rosbag2 store it.

Every topic tcomp writes (copied inputs keep their own) is offered reliable, keep-last-10,
volatile: what ``ros2 bag play`` should offer subscribers, as a sensor driver would.
"""

from __future__ import annotations

from collections.abc import Sequence
from io import StringIO
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rosbags.interfaces import Qos

__all__ = ["offered_qos", "qos_from_text", "qos_yaml"]


def offered_qos() -> list[Qos]:
    """Reliable, keep-last-10, volatile, as a list of one rosbags QoS profile."""
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    unset = QosTime(sec=0, nsec=0)
    return [
        Qos(
            history=QosHistory.KEEP_LAST,
            depth=10,
            reliability=QosReliability.RELIABLE,
            durability=QosDurability.VOLATILE,
            deadline=unset,
            lifespan=unset,
            liveliness=QosLiveliness.AUTOMATIC,
            liveliness_lease_duration=unset,
            avoid_ros_namespace_conventions=False,
        )
    ]


def qos_yaml(profiles: Sequence[Qos]) -> tuple[str, Any]:
    """Offered QoS as rosbag2 stores it: the channel metadata string and the yaml structure."""
    from rosbags.rosbag2.metadata import dump_qos_v9
    from ruamel.yaml import YAML

    dumped = dump_qos_v9(list(profiles))
    stream = StringIO()
    yaml = YAML(typ="safe")
    yaml.default_flow_style = False
    yaml.dump(dumped, stream)
    return stream.getvalue().strip(), dumped


def qos_from_text(text: str) -> Any:
    """The yaml structure of an ``offered_qos_profiles`` channel metadata string."""
    from ruamel.yaml import YAML

    return YAML(typ="safe").load(text) if text.strip() else []
