//! The `joint_bridge` ROS 2 node alone in its process: see [`joint_bridge::node`].

fn main() -> std::process::ExitCode {
    node_runtime::node_main("joint_bridge", joint_bridge::node::run)
}
