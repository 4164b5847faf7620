//! The `gait_planner` ROS 2 node alone in its process: see [`gait_planner::node`].

fn main() -> std::process::ExitCode {
    node_runtime::node_main("gait_planner", gait_planner::node::run)
}
