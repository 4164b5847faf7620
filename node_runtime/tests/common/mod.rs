//! What the node_runtime tests share: each test re-run in a private network namespace, nodes
//! started with no arguments, and waits for DDS discovery between two sides.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use biped_msgs::msg::StringMsg;
use node_runtime::{Host, NodeSetup, RosNode, Subscription};

const INSIDE: &str = "BIPED_TEST_IN_NETNS";

/// Runs the calling test again in a private network namespace; true inside it (go on),
/// false outside (its result is asserted here).
pub fn in_private_network(test: &str, domain_id: u32) -> bool {
    if std::env::var_os(INSIDE).is_some() {
        return true;
    }
    let out = std::process::Command::new("unshare")
        .args([
            "-n",
            "sh",
            "-c",
            "ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo || exit 90\nexec \"$@\"",
            "sh",
        ])
        .arg(std::env::current_exe().unwrap())
        .args([test, "--exact", "--nocapture", "--test-threads=1"])
        .env(INSIDE, "1")
        .env("ROS_DOMAIN_ID", domain_id.to_string())
        .env("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        .env_remove("ROS_LOCALHOST_ONLY")
        .output()
        .expect("unshare runs (root needed for a private network namespace)");
    let text = format!(
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.status.success(),
        "{test} in its network namespace:\n{text}"
    );
    assert!(text.contains("1 passed"), "{test} did not run:\n{text}");
    false
}

pub fn node(host: &Host, name: &str) -> RosNode {
    let setup = NodeSetup::from_args(Vec::<String>::new(), name).unwrap();
    RosNode::start(host, setup, &BTreeMap::new(), None).unwrap()
}

pub fn text(s: &str) -> StringMsg {
    StringMsg { data: s.to_owned() }
}

/// Everything `sub` gets within `quiet` of the last message (or of the call).
pub fn drain(sub: &Subscription<StringMsg>, quiet: Duration) -> Vec<String> {
    let mut got = Vec::new();
    let mut last = Instant::now();
    while last.elapsed() < quiet {
        match sub.take().unwrap() {
            Some((m, _)) => {
                got.push(m.data);
                last = Instant::now();
            }
            None => std::thread::sleep(Duration::from_millis(2)),
        }
    }
    got
}

/// Publishes `probe` until `sub` has it (DDS discovery between the two sides is done).
pub fn until_heard(publish: impl Fn(StringMsg), sub: &Subscription<StringMsg>, probe: &str) {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        publish(text(probe));
        if drain(sub, Duration::from_millis(100))
            .iter()
            .any(|m| m == probe)
        {
            return;
        }
        assert!(Instant::now() < deadline, "`{probe}` not heard within 30 s");
    }
}
