"""The rclpy relay of benches/pipeline.rs: the comparison for our `ik_solver` node.

Subscribes /gait/ankle_targets (biped_msgs/msg/AnkleTargets) and, for each message, publishes
/joint_commands (sensor_msgs/msg/JointState) with the same header, the joint names given on
the command line and as many positions (copied from the targets: no IK is computed; the Rust
closed-form IK of both legs takes about 0.3 us, so it does not matter for the comparison).
QoS as the fleet's: reliable, volatile, keep last 10 (rclpy's default for a depth of 10).
Single-threaded executor, rclpy's default. Prints its rclpy, rmw and Fast DDS versions on stdout.

    biped-python pipeline_relay.py JOINT_NAME...

Run by the bench inside its private network namespace; stops on SIGINT.
"""

import sys
from importlib.metadata import PackageNotFoundError, version

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.utilities import get_rmw_implementation_identifier
from sensor_msgs.msg import JointState
from biped_msgs.msg import AnkleTargets


def dist_version(name):
    try:
        return version(name)
    except PackageNotFoundError:
        return "?"


def main():
    names = sys.argv[1:]
    rclpy.init()
    node = rclpy.create_node("rclpy_relay")
    pub = node.create_publisher(JointState, "/joint_commands", 10)

    def relay(m):
        a, b = m.left_ankle, m.right_ankle
        values = [a.x, a.y, a.z, m.left_foot_yaw, b.x, b.y, b.z, m.right_foot_yaw]
        js = JointState()
        js.header = m.header
        js.name = names
        js.position = [values[i % len(values)] for i in range(len(names))]
        pub.publish(js)

    node.create_subscription(AnkleTargets, "/gait/ankle_targets", relay, 10)
    print(f"rclpy {dist_version('ros-rclpy')} on {get_rmw_implementation_identifier()} "
          f"(Fast DDS {dist_version('ros-fastrtps')})", flush=True)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
