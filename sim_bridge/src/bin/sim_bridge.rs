//! The `sim_bridge` ROS 2 node alone in its process: see [`sim_bridge::node`].

fn main() -> std::process::ExitCode {
    node_runtime::node_main("sim_bridge", sim_bridge::node::run)
}
