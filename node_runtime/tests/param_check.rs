//! A node's parameter check (the `check` given to [`RosNode::start`]) sees every set made
//! once the node runs, a set back to a start-up value too: a node that applies what its check
//! accepts would otherwise keep the value set before while `ros2 param get` says the
//! start-up one. The test re-runs itself in a private network namespace with only loopback
//! (root), on ROS_DOMAIN_ID 192.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

use common::in_private_network;
use node_runtime::{Host, NodeSetup, ParameterCheck, RosNode};
use ros2_client::ParameterValue;

#[test]
fn a_parameter_set_back_to_its_start_up_value_reaches_the_nodes_check() {
    if !in_private_network(
        "a_parameter_set_back_to_its_start_up_value_reaches_the_nodes_check",
        192,
    ) {
        return;
    }
    let seen: Arc<Mutex<Vec<(String, f64)>>> = Arc::default();
    let check: ParameterCheck = {
        let seen = seen.clone();
        Box::new(move |name: &str, value: &ParameterValue| {
            let ParameterValue::Double(v) = value else {
                return Err(format!("{name}: not a double"));
            };
            seen.lock().unwrap().push((name.to_owned(), *v));
            if *v < 0.0 {
                Err(format!("{name} = {v} is negative"))
            } else {
                Ok(())
            }
        })
    };
    let declared = BTreeMap::from([("gain".to_owned(), ParameterValue::Double(1.0))]);
    let setup = NodeSetup::from_args(Vec::<String>::new(), "checked").unwrap();
    let ros = RosNode::start(&Host::process().unwrap(), setup, &declared, Some(check)).unwrap();
    // The start-up value is the node's already: not checked.
    assert!(
        seen.lock().unwrap().is_empty(),
        "{:?}",
        seen.lock().unwrap()
    );

    ros.node
        .set_parameter("gain", ParameterValue::Double(2.0))
        .unwrap();
    ros.node
        .set_parameter("gain", ParameterValue::Double(1.0))
        .unwrap();
    let e = ros
        .node
        .set_parameter("gain", ParameterValue::Double(-1.0))
        .unwrap_err();
    assert!(e.contains("gain = -1 is negative"), "{e}");
    assert_eq!(
        *seen.lock().unwrap(),
        [
            ("gain".to_owned(), 2.0),
            ("gain".to_owned(), 1.0),
            ("gain".to_owned(), -1.0)
        ]
    );
    // The store holds the last value the check accepted.
    assert_eq!(
        ros.node.get_parameter("gain"),
        Some(ParameterValue::Double(1.0))
    );
}
