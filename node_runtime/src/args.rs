//! The ROS 2 command line of a node: what follows `--ros-args` (remaps, node name and
//! namespace, parameter files, `-p`, `--log-level`), and topic names resolved through it.

use ros2_client::Name;
use serde_norway::Value;

use crate::error::RosError;

/// The ROS part of a node's command line: what follows `--ros-args` (until `--`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RosArgs {
    /// Topic and service remaps `from` → `to` (`-r from:=to`).
    pub remaps: Vec<(String, String)>,
    /// Node name override (`-r __node:=name`).
    pub node_name: Option<String>,
    /// Namespace override (`-r __ns:=/ns`).
    pub namespace: Option<String>,
    /// Parameter files, in order (`--params-file FILE`).
    pub params_files: Vec<String>,
    /// Single parameters (`-p name:=value`), the value parsed as YAML.
    pub params: Vec<(String, Value)>,
    /// `--log-level`.
    pub log_level: Option<String>,
}

impl RosArgs {
    /// Splits a command line into the node's own arguments and the ROS arguments.
    /// Remaps and parameters may be prefixed with `node_name:` to target one node; others are
    /// dropped.
    pub fn parse(
        args: impl IntoIterator<Item = String>,
        node: &str,
    ) -> Result<(Vec<String>, RosArgs), RosError> {
        let mut own = Vec::new();
        let mut ros = RosArgs::default();
        let mut it = args.into_iter();
        let mut in_ros = false;
        while let Some(a) = it.next() {
            if a == "--ros-args" {
                in_ros = true;
                continue;
            }
            if !in_ros {
                own.push(a);
                continue;
            }
            let mut value = |flag: &str| {
                it.next()
                    .ok_or_else(|| RosError::Args(format!("{flag} needs a value")))
            };
            match a.as_str() {
                "--" => in_ros = false,
                "-r" | "--remap" => {
                    let v = value(&a)?;
                    if let Some((from, to)) = targeted(&v, node)? {
                        match from.as_str() {
                            "__node" | "__name" => ros.node_name = Some(to),
                            "__ns" => ros.namespace = Some(to),
                            _ => ros.remaps.push((from, to)),
                        }
                    }
                }
                "-p" | "--param" => {
                    let v = value(&a)?;
                    if let Some((name, text)) = targeted(&v, node)? {
                        let parsed = serde_norway::from_str(&text).map_err(|e| {
                            RosError::Args(format!("-p {v}: value `{text}` is not YAML: {e}"))
                        })?;
                        ros.params.push((name, parsed));
                    }
                }
                "--params-file" => ros.params_files.push(value(&a)?),
                "--log-level" => ros.log_level = Some(value(&a)?),
                "-e" | "--enclave" => {
                    let enclave = value(&a)?;
                    return Err(RosError::Args(format!(
                        "{a} {enclave}: ROS 2 security (SROS2 enclaves) is not supported: these nodes speak DDS through RustDDS without DDS Security, so they would join the graph unsecured; run them without {a} (and outside a secured graph)"
                    )));
                }
                other => return Err(RosError::Args(format!("unknown ROS argument `{other}`"))),
            }
        }
        Ok((own, ros))
    }
}

/// `[node:]from:=to` → `(from, to)` if it is for `node` (or for every node).
fn targeted(arg: &str, node: &str) -> Result<Option<(String, String)>, RosError> {
    let (lhs, rhs) = arg
        .split_once(":=")
        .ok_or_else(|| RosError::Args(format!("`{arg}` is not of the form name:=value")))?;
    let (target, lhs) = match lhs.split_once(':') {
        Some((t, l)) if !t.starts_with('/') || !l.is_empty() => (Some(t), l),
        _ => (None, lhs),
    };
    if lhs.is_empty() {
        return Err(RosError::Args(format!("`{arg}` has an empty name")));
    }
    Ok(match target {
        Some(t) if t != node => None,
        _ => Some((lhs.to_owned(), rhs.to_owned())),
    })
}

/// A topic name after the node's remaps, resolved in its namespace: `cmd_vel` in `/` is
/// `/cmd_vel`, in `/robot1` it is `/robot1/cmd_vel`; absolute names stay as they are.
pub fn topic_name(args: &RosArgs, namespace: &str, name: &str) -> Result<Name, RosError> {
    let ns = namespace.trim_end_matches('/');
    let resolve = |n: &str| {
        if n.starts_with('/') {
            n.to_owned()
        } else {
            format!("{ns}/{n}")
        }
    };
    let full = resolve(name);
    let mapped = args
        .remaps
        .iter()
        .rev()
        .find(|(from, _)| resolve(from) == full)
        .map(|(_, to)| resolve(to))
        .unwrap_or(full);
    Name::parse(&mapped).map_err(|e| RosError::Args(format!("topic name `{mapped}`: {e:?}")))
}
