//! Parameters: ROS 2 parameter files and `-p` overrides for one node (nested mappings as
//! dotted names), YAML values to and from ROS parameter values, and the checks a node applies
//! (unknown names, sets from peers).

use std::collections::BTreeMap;

use ros2_client::ParameterValue;
use serde_norway::{Mapping, Value};

use crate::args::RosArgs;
use crate::error::RosError;

fn flatten(prefix: &str, value: &Value, out: &mut BTreeMap<String, Value>) {
    match value {
        Value::Mapping(m) => {
            for (k, v) in m {
                let key = k
                    .as_str()
                    .map(String::from)
                    .unwrap_or_else(|| format!("{k:?}"));
                let name = if prefix.is_empty() {
                    key
                } else {
                    format!("{prefix}.{key}")
                };
                flatten(&name, v, out);
            }
        }
        other => {
            out.insert(prefix.to_owned(), other.clone());
        }
    }
}

/// The parameters of node `node` in namespace `namespace` from ROS 2 parameter files (the
/// `/**` wildcard section, then `node`, `/node`, `ns/node` or `/ns/node`, nested mappings as
/// dotted names), then the `-p` overrides. Sections of other nodes are ignored.
pub fn node_parameters(
    args: &RosArgs,
    node: &str,
    namespace: &str,
) -> Result<BTreeMap<String, Value>, RosError> {
    let ns = namespace.trim_matches('/');
    let fqn = if ns.is_empty() {
        format!("/{node}")
    } else {
        format!("/{ns}/{node}")
    };
    let mut out = BTreeMap::new();
    for path in &args.params_files {
        let text = std::fs::read_to_string(path)
            .map_err(|e| RosError::Params(format!("cannot read {path}: {e}")))?;
        let doc: Value =
            serde_norway::from_str(&text).map_err(|e| RosError::Params(format!("{path}: {e}")))?;
        let top = doc.as_mapping().cloned().unwrap_or_else(Mapping::new);
        for pass in 0..2 {
            for (k, v) in &top {
                let key = k.as_str().unwrap_or_default();
                let section = if key.starts_with('/') {
                    key.to_owned()
                } else {
                    format!("/{key}")
                };
                let wildcard = key == "/**";
                let ours = section == fqn
                    || (ns.is_empty() && section == format!("/{node}"))
                    || section == format!("/**/{node}")
                    || key == node;
                if (pass == 0 && !wildcard) || (pass == 1 && !ours) {
                    continue;
                }
                let params = v.get("ros__parameters").ok_or_else(|| {
                    RosError::Params(format!("{path}: section `{key}` has no `ros__parameters`"))
                })?;
                flatten("", params, &mut out);
            }
        }
    }
    for (name, value) in &args.params {
        out.insert(name.clone(), value.clone());
    }
    Ok(out)
}

/// A YAML value as a ROS parameter value.
pub fn to_parameter_value(name: &str, v: &Value) -> Result<ParameterValue, RosError> {
    let bad = || {
        RosError::Params(format!(
            "parameter `{name}`: value {v:?} has no ROS parameter type"
        ))
    };
    Ok(match v {
        Value::Bool(b) => ParameterValue::Boolean(*b),
        Value::Number(n) if n.is_i64() => ParameterValue::Integer(n.as_i64().ok_or_else(bad)?),
        Value::Number(n) => ParameterValue::Double(n.as_f64().ok_or_else(bad)?),
        Value::String(s) => ParameterValue::String(s.clone()),
        Value::Sequence(items) => {
            if items.iter().all(Value::is_bool) {
                ParameterValue::BooleanArray(items.iter().filter_map(Value::as_bool).collect())
            } else if items.iter().all(Value::is_i64) {
                ParameterValue::IntegerArray(items.iter().filter_map(Value::as_i64).collect())
            } else if items.iter().all(Value::is_number) {
                ParameterValue::DoubleArray(items.iter().filter_map(Value::as_f64).collect())
            } else if items.iter().all(Value::is_string) {
                ParameterValue::StringArray(
                    items
                        .iter()
                        .filter_map(|s| s.as_str().map(String::from))
                        .collect(),
                )
            } else {
                return Err(bad());
            }
        }
        _ => return Err(bad()),
    })
}

/// A ROS parameter value as YAML, to feed a node's typed parameter struct.
pub fn from_parameter_value(v: &ParameterValue) -> Value {
    match v {
        ParameterValue::NotSet => Value::Null,
        ParameterValue::Boolean(b) => Value::Bool(*b),
        ParameterValue::Integer(i) => Value::from(*i),
        ParameterValue::Double(d) => Value::from(*d),
        ParameterValue::String(s) => Value::String(s.clone()),
        ParameterValue::ByteArray(b) => {
            Value::Sequence(b.iter().map(|x| Value::from(*x)).collect())
        }
        ParameterValue::BooleanArray(b) => {
            Value::Sequence(b.iter().map(|x| Value::Bool(*x)).collect())
        }
        ParameterValue::IntegerArray(b) => {
            Value::Sequence(b.iter().map(|x| Value::from(*x)).collect())
        }
        ParameterValue::DoubleArray(b) => {
            Value::Sequence(b.iter().map(|x| Value::from(*x)).collect())
        }
        ParameterValue::StringArray(b) => {
            Value::Sequence(b.iter().map(|x| Value::String(x.clone())).collect())
        }
    }
}

/// A parameter validator: `Err(reason)` refuses a set from a ROS peer.
pub type ParameterCheck = Box<dyn Fn(&str, &ParameterValue) -> Result<(), String> + Send + Sync>;

/// Why a set of parameter `name` from a peer is refused: the node reads it at start-up.
pub fn read_at_startup_only(name: &str) -> String {
    format!("{name} is read at start-up; restart the node to change it")
}

/// The check of a node whose parameters are all read at start-up: a set from a peer is
/// refused with the reason (`use_sim_time` aside).
pub fn read_at_startup() -> ParameterCheck {
    Box::new(|name: &str, _: &ParameterValue| {
        if name == "use_sim_time" {
            Ok(())
        } else {
            Err(read_at_startup_only(name))
        }
    })
}

/// The parameters every node takes besides its own: ROS's `use_sim_time`, `cpu_affinity`
/// (the CPUs its process is bound to, [`crate::affinity`]), `cpu_dma_latency_us` (a CPU
/// latency request its process holds, [`crate::cpu_latency`]) and `thread_priority` (its
/// threads under real-time scheduling, [`crate::priority`]).
pub const COMMON_PARAMS: [&str; 4] = [
    "use_sim_time",
    crate::affinity::CPU_AFFINITY_PARAM,
    crate::cpu_latency::CPU_DMA_LATENCY_PARAM,
    crate::priority::THREAD_PRIORITY_PARAM,
];

/// Rejects any parameter not in `known` (besides [`COMMON_PARAMS`]), naming it.
pub fn check_known(params: &BTreeMap<String, Value>, known: &[&str]) -> Result<(), RosError> {
    for k in params.keys() {
        if !COMMON_PARAMS.contains(&k.as_str()) && !known.contains(&k.as_str()) {
            return Err(RosError::Params(format!(
                "unknown parameter `{k}` (known: {})",
                known
                    .iter()
                    .chain(&COMMON_PARAMS)
                    .copied()
                    .collect::<Vec<_>>()
                    .join(", ")
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
pub(crate) mod tests {
    #![allow(clippy::unwrap_used)]

    /// A parameter value written as YAML, as a parameter file or `-p` holds it.
    pub(crate) fn yaml(text: &str) -> serde_norway::Value {
        serde_norway::from_str(text).unwrap()
    }
}
