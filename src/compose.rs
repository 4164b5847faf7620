//! `biped compose`: several of the fleet's nodes in one process, as ROS 2's component
//! container runs composable nodes. Each node runs the code its own binary runs
//! ([`ik_solver::node::run`] and so on); all share one DDS participant, and a message one
//! of them publishes reaches the others in-process ([`node_runtime::local`]), while every
//! topic stays on DDS for peers outside the process, under the same names, types and QoS.
//! What it saves: the DDS hops between the composed nodes (a serialisation, two processes'
//! DDS threads and a loopback datagram each) and their participants' discovery traffic.
//!
//! The nodes run on one thread by default (`--executor single`, as `component_container`'s
//! single-threaded executor): a message between them is handed over without waking another
//! thread. `--executor per-node` gives each node its own thread (as
//! `component_container_isolated`), for a node that blocks, such as a joint bridge on a
//! serial bus waiting for its servos' answers.
//!
//! Command line: `biped compose [--executor single|per-node] --node <name> [--ros-args ...]
//! --node <name> [...]`, each node's arguments as its own binary takes them. SIGINT or
//! SIGTERM stops every node; a node that ends or fails stops the others, and the process
//! fails naming it.

use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use anyhow::Context as _;
use node_runtime::{Host, NodeSetup};
use smol::future::FutureExt as _;

/// A composable node's run: its future runs the node until its host stops.
pub type NodeRun = fn(NodeSetup, Host) -> NodeFuture;

/// A node running (not `Send`: it stays on the thread that starts it).
pub type NodeFuture = Pin<Box<dyn Future<Output = anyhow::Result<()>>>>;

/// The nodes that can be composed, with the function their own binary runs.
pub const COMPOSABLE: [(&str, NodeRun); 4] = [
    ("gait_planner", |s, h| {
        Box::pin(gait_planner::node::run(s, h))
    }),
    ("ik_solver", |s, h| Box::pin(ik_solver::node::run(s, h))),
    ("joint_bridge", |s, h| {
        Box::pin(joint_bridge::node::run(s, h))
    }),
    ("sim_bridge", |s, h| Box::pin(sim_bridge::node::run(s, h))),
];

/// The function that runs the composable node `name`; `None` for another name.
pub fn node_run(name: &str) -> Option<NodeRun> {
    COMPOSABLE.iter().find(|(n, _)| *n == name).map(|(_, r)| *r)
}

/// How the composed nodes share threads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Executor {
    /// All on one thread (the default).
    #[default]
    Single,
    /// Each node on its own thread.
    PerNode,
}

impl Executor {
    /// The value `--executor` takes for it.
    pub fn as_arg(self) -> &'static str {
        match self {
            Executor::Single => "single",
            Executor::PerNode => "per-node",
        }
    }
}

/// What `biped compose` was asked: the executor and each node's name and arguments.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Composition {
    pub executor: Executor,
    pub nodes: Vec<(String, Vec<String>)>,
}

/// Splits `[--executor E] --node a ARGS... --node b ARGS...`.
pub fn parse(args: &[String]) -> anyhow::Result<Composition> {
    let mut executor = None;
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
        } else if let Some((_, node_args)) = nodes.last_mut() {
            node_args.push(a.clone());
        } else if a == "--executor" && executor.is_none() {
            let e = it.next().map(String::as_str);
            executor = Some(
                [Executor::Single, Executor::PerNode]
                    .into_iter()
                    .find(|x| Some(x.as_arg()) == e)
                    .with_context(|| {
                        format!("--executor {}: not single or per-node", e.unwrap_or(""))
                    })?,
            );
        } else {
            anyhow::bail!("`{a}` before the first --node");
        }
    }
    if nodes.is_empty() {
        anyhow::bail!("no nodes to compose: give --node <name> [--ros-args ...] for each");
    }
    Ok(Composition {
        executor: executor.unwrap_or_default(),
        nodes,
    })
}

/// Runs `run` as the node `name` of `host` to its end, which stops the other nodes of the
/// host (they are one unit to the launcher). A panic is a failure like any other: the other
/// nodes still stop (the joint bridge with torque off) and the process fails, naming it.
async fn run_to_end(
    name: String,
    run: NodeRun,
    setup: NodeSetup,
    host: Host,
) -> (String, anyhow::Result<()>) {
    let result = std::panic::AssertUnwindSafe(run(setup, host.clone()))
        .catch_unwind()
        .await
        .unwrap_or_else(|_| Err(anyhow::anyhow!("panicked (see above)")));
    host.request_stop();
    (name, result)
}

/// Runs the nodes of `args` in this process until SIGINT/SIGTERM or until one of them ends.
pub fn compose(args: &[String]) -> anyhow::Result<()> {
    let composition = parse(args)?;
    // Every node's arguments and parameter files are read before any joins DDS.
    let nodes = composition
        .nodes
        .iter()
        .map(|(name, a)| {
            let setup = NodeSetup::from_args(a.iter().cloned(), name)
                .with_context(|| format!("{name}'s arguments"))?;
            // The nodes share this process (and its DDS thread): it cannot be bound per node.
            if setup.cpu_affinity()?.is_some() {
                anyhow::bail!(
                    "{name}: parameter `{}` binds a node's own process; composed nodes share \
                     one: bind `biped compose` itself (e.g. `taskset -c 0 biped compose ...`)",
                    node_runtime::CPU_AFFINITY_PARAM
                );
            }
            let run = node_run(name).context("parse takes only composable nodes")?;
            Ok((name.clone(), run, setup))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    // A CPU latency request is the whole machine's: the lowest any node asks for is held for
    // the process, until it ends.
    let requests = nodes
        .iter()
        .map(|(name, _, setup)| {
            setup
                .cpu_dma_latency_us()
                .with_context(|| format!("{name}'s parameters"))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let _latency = requests
        .into_iter()
        .flatten()
        .min()
        .map(node_runtime::CpuLatencyRequest::hold)
        .transpose()?;
    // The nodes share their threads (the DDS threads always): the process runs under
    // real-time scheduling at the highest priority any node asks for, before any thread starts.
    let priorities = nodes
        .iter()
        .map(|(name, _, setup)| {
            setup
                .thread_priority()
                .with_context(|| format!("{name}'s parameters"))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    if let Some(priority) = priorities.into_iter().flatten().max() {
        node_runtime::priority::run_this_thread_realtime(priority)?;
    }
    let stop: Arc<AtomicBool> = node_runtime::shutdown_flag()?;
    let host = Host::composed(stop)?;
    eprintln!(
        "biped compose: {} {}",
        composition
            .nodes
            .iter()
            .map(|(n, _)| n.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        match composition.executor {
            Executor::Single => "on one thread (--executor single)",
            Executor::PerNode => "each on its own thread (--executor per-node)",
        }
    );
    let (done_tx, done_rx) = smol::channel::unbounded::<(String, anyhow::Result<()>)>();
    let count = nodes.len();
    let mut threads = Vec::new();
    let mut results = Vec::new();
    match composition.executor {
        Executor::Single => {
            let executor = smol::LocalExecutor::new();
            for (name, run, setup) in nodes {
                let done = done_tx.clone();
                let node = run_to_end(name, run, setup, host.clone());
                executor
                    .spawn(async move {
                        let _ = done.send(node.await).await;
                    })
                    .detach();
            }
            node_runtime::wait::block_on(executor.run(async {
                for _ in 0..count {
                    results.extend(done_rx.recv().await.ok());
                }
            }));
        }
        Executor::PerNode => {
            for (name, run, setup) in nodes {
                let (host, done) = (host.clone(), done_tx.clone());
                let thread = std::thread::Builder::new()
                    .name(name.clone())
                    // The simulator's MuJoCo and the planner's searches get a main thread's
                    // stack.
                    .stack_size(8 << 20)
                    .spawn(move || {
                        let _ = done.send_blocking(node_runtime::wait::block_on(run_to_end(
                            name, run, setup, host,
                        )));
                    })
                    .context("cannot start a node's thread")?;
                threads.push(thread);
            }
            drop(done_tx);
            results.extend(std::iter::from_fn(|| done_rx.recv_blocking().ok()));
        }
    }
    for t in threads {
        let _ = t.join();
    }
    // In the order the nodes ended: the first failure is the cause.
    let mut first_failure: Option<anyhow::Error> = None;
    for (name, result) in results {
        match result {
            Err(e) if first_failure.is_none() => {
                first_failure = Some(e.context(format!("{name} failed")));
            }
            Err(e) => eprintln!("biped compose: {name} failed too: {e:#}"),
            Ok(()) => {}
        }
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
    fn each_node_gets_the_arguments_after_its_name_on_one_thread_unless_asked() {
        let c = parse(&args(
            "--node ik_solver --ros-args -r __ns:=/a --node joint_bridge --ros-args -p backend:=mock",
        ))
        .expect("valid");
        assert_eq!(c.executor, Executor::Single);
        assert_eq!(
            c.nodes,
            vec![
                ("ik_solver".to_owned(), args("--ros-args -r __ns:=/a")),
                (
                    "joint_bridge".to_owned(),
                    args("--ros-args -p backend:=mock")
                ),
            ]
        );
        let c = parse(&args(
            "--executor per-node --node ik_solver --executor single",
        ))
        .expect("valid");
        assert_eq!(c.executor, Executor::PerNode);
        // After a --node, it is that node's argument (which the node will refuse).
        assert_eq!(c.nodes[0].1, args("--executor single"));
    }

    #[test]
    fn unknown_repeated_or_missing_nodes_and_executors_are_refused_by_name() {
        let err = |s: &str| format!("{:#}", parse(&args(s)).expect_err(s));
        assert!(err("--node teleop").contains("teleop: not a composable node"));
        assert!(err("--node ik_solver --node ik_solver").contains("ik_solver given twice"));
        assert!(err("--ros-args --node ik_solver").contains("`--ros-args` before the first"));
        assert!(err("").contains("no nodes to compose"));
        assert!(err("--node").contains("needs a node name"));
        assert!(
            err("--executor multi --node ik_solver")
                .contains("--executor multi: not single or per-node")
        );
        assert!(
            err("--executor single --executor single --node ik_solver")
                .contains("`--executor` before the first")
        );
    }
}
