//! The `ik_solver` ROS 2 node alone in its process: see [`ik_solver::node`].

fn main() -> std::process::ExitCode {
    node_runtime::node_main("ik_solver", ik_solver::node::run)
}
