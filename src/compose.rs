//! `biped compose`: several of the fleet's nodes in one process, as ROS 2's component
//! container runs composable nodes. Each node runs on its own thread with the code its own
//! binary runs ([`ik_solver::node::run`] and so on); all share one DDS participant, and a
//! message one of them publishes reaches the others in-process ([`node_runtime::local`]),
//! while every topic stays on DDS for peers outside the process, under the same names,
//! types and QoS. What it saves: the DDS hops between the composed nodes (a serialisation,
//! two processes' DDS threads and a loopback datagram each) and their participants' discovery
//! traffic.
//!
//! Command line: `biped compose --node <name> [--ros-args ...] --node <name> [...]`, each
//! node's arguments as its own binary takes them. SIGINT or SIGTERM stops every node; a
//! node that ends or fails stops the others, and the process fails naming it.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use anyhow::Context as _;
use node_runtime::{Host, NodeSetup};

/// The nodes that can be composed, with the function their own binary runs.
pub const COMPOSABLE: [(&str, NodeRun); 4] = [
    ("gait_planner", gait_planner::node::run),
    ("ik_solver", ik_solver::node::run),
    ("joint_bridge", joint_bridge::node::run),
    ("sim_bridge", sim_bridge::node::run),
];

/// A node's main function after its setup: runs until its host stops.
pub type NodeRun = fn(NodeSetup, &Host) -> anyhow::Result<()>;

/// The function that runs the composable node `name`; `None` for another name.
pub fn node_run(name: &str) -> Option<NodeRun> {
    COMPOSABLE.iter().find(|(n, _)| *n == name).map(|(_, r)| *r)
}

/// Splits `--node a ARGS... --node b ARGS...` into each node's name and arguments.
pub fn split_nodes(args: &[String]) -> anyhow::Result<Vec<(String, Vec<String>)>> {
    let mut nodes: Vec<(String, Vec<String>)> = Vec::new();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        if a == "--node" {
            let name = it.next().context("--node needs a node name")?.to_owned();
            if node_run(&name).is_none() {
                anyhow::bail!(
                    "--node {name}: not a composable node (one of {})",
                    COMPOSABLE.map(|(n, _)| n).join(", ")
                );
            }
            if nodes.iter().any(|(n, _)| *n == name) {
                anyhow::bail!("--node {name} given twice");
            }
            nodes.push((name, Vec::new()));
        } else {
            match nodes.last_mut() {
                Some((_, node_args)) => node_args.push(a.clone()),
                None => anyhow::bail!("`{a}` before the first --node"),
            }
        }
    }
    if nodes.is_empty() {
        anyhow::bail!("no nodes to compose: give --node <name> [--ros-args ...] for each");
    }
    Ok(nodes)
}

/// Runs the nodes of `args` in this process until SIGINT/SIGTERM or until one of them ends.
pub fn compose(args: &[String]) -> anyhow::Result<()> {
    let nodes = split_nodes(args)?;
    // Every node's arguments and parameter files are read before any joins DDS.
    let setups = nodes
        .iter()
        .map(|(name, a)| {
            NodeSetup::from_args(a.iter().cloned(), name)
                .with_context(|| format!("{name}'s arguments"))
                .map(|s| (name.clone(), s))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let stop: Arc<AtomicBool> = node_runtime::shutdown_flag()?;
    let host = Host::composed(stop)?;
    let (done_tx, done_rx) = std::sync::mpsc::channel::<(String, anyhow::Result<()>)>();
    let mut threads = Vec::new();
    for (name, setup) in setups {
        let run = node_run(&name).context("split_nodes takes only composable nodes")?;
        let (host, done) = (host.clone(), done_tx.clone());
        let thread = std::thread::Builder::new()
            .name(name.clone())
            // The simulator's MuJoCo and the planner's searches get a main thread's stack.
            .stack_size(8 << 20)
            .spawn(move || {
                // A panic is a failure like any other: the other nodes still stop (the
                // joint bridge with torque off) and the process fails, naming the node.
                let result =
                    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| run(setup, &host)))
                        .unwrap_or_else(|_| Err(anyhow::anyhow!("panicked (see above)")));
                // One node gone stops the others: they are one unit to the launcher.
                host.request_stop();
                let _ = done.send((name, result));
            })
            .context("cannot start a node's thread")?;
        threads.push(thread);
    }
    drop(done_tx);
    let mut first_failure: Option<anyhow::Error> = None;
    for (name, result) in done_rx {
        match result {
            Err(e) if first_failure.is_none() => {
                first_failure = Some(e.context(format!("{name} failed")));
            }
            Err(e) => eprintln!("biped compose: {name} failed too: {e:#}"),
            Ok(()) => {}
        }
    }
    for t in threads {
        let _ = t.join();
    }
    first_failure.map_or(Ok(()), Err)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(s: &str) -> Vec<String> {
        s.split_whitespace().map(str::to_owned).collect()
    }

    #[test]
    fn each_node_gets_the_arguments_after_its_name() {
        let nodes = split_nodes(&args(
            "--node ik_solver --ros-args -r __ns:=/a --node joint_bridge --ros-args -p backend:=mock",
        ))
        .expect("valid");
        assert_eq!(
            nodes,
            vec![
                ("ik_solver".to_owned(), args("--ros-args -r __ns:=/a")),
                (
                    "joint_bridge".to_owned(),
                    args("--ros-args -p backend:=mock")
                ),
            ]
        );
    }

    #[test]
    fn unknown_repeated_or_missing_nodes_are_refused_by_name() {
        let err = |s: &str| format!("{:#}", split_nodes(&args(s)).expect_err(s));
        assert!(err("--node teleop").contains("teleop: not a composable node"));
        assert!(err("--node ik_solver --node ik_solver").contains("ik_solver given twice"));
        assert!(err("--ros-args --node ik_solver").contains("`--ros-args` before the first"));
        assert!(err("").contains("no nodes to compose"));
        assert!(err("--node").contains("needs a node name"));
    }
}
