"""ROS 2 nodes (rclpy): ``virtmech ros2 SCENARIO`` renders a scenario's mechanism on a device
served by a ROS 2 driver; ``virtmech ros2-sim SCENARIO`` serves the scenario's simulated
device on the same topics, so that the pair runs with no hardware. docs/ros2.md.

    virtmech ros2 omni-fig11 --ros-args -r joint_states:=/phantom/joint_states
    virtmech ros2-sim omni-fig11

Needs the [ros2] extra (the ROS 2 Jazzy wheels: ``pip install 'virtmech[ros2]'``); nothing
here imports rclpy until a node starts, so ``import virtmech`` never needs ROS.

- joint_map: the driver's joints <-> the device's (the Touch's ROS 2 drivers by default)
- render:    what the node does with each message (no ROS: tested on its own)
- node:      the rendering node; sim_node: the simulated device's node
- markers:   the MarkerArray for RViz; runtime: rclpy's context, parameters, spin
"""

from __future__ import annotations

__all__: list[str] = []
