"""The compensator node declares its parameters from the one schema, descriptors included."""

from __future__ import annotations

from tcomp_core.parameters import PARAMETERS


def test_the_node_declares_exactly_the_schema(ros_context):
    from tcomp_ros.compensator import CompensatorNode

    node = CompensatorNode(context=ros_context, background=False)
    try:
        for spec in PARAMETERS:
            assert node.get_parameter(spec.name).value == spec.default, spec.name
            described = node.describe_parameter(spec.name)
            assert described.description == spec.description
            assert described.read_only == spec.read_only
        rclpy_own = {"use_sim_time", "start_type_description_service"}
        declared = {name for name in node._parameters if name not in rclpy_own}
        assert declared == {spec.name for spec in PARAMETERS}
    finally:
        node.destroy_node()
