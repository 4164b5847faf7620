//! Nodes composed in one process ([`Host::composed`]): a message between them arrives once,
//! in-process (not a second time through DDS), and peers outside the process still send
//! and receive on the same topics through DDS. Each test re-runs itself in a private
//! network namespace with only loopback (root), on its own ROS_DOMAIN_ID (190-193), DDS
//! discovery restricted to the host.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use biped_msgs::msg::StringMsg;
use common::{drain, in_private_network, node, text, until_heard};
use node_runtime::Host;

fn composed() -> Host {
    Host::composed(Arc::new(AtomicBool::new(false))).unwrap()
}

#[test]
fn a_composed_subscriber_gets_each_message_once_from_its_process_and_from_outside() {
    if !in_private_network(
        "a_composed_subscriber_gets_each_message_once_from_its_process_and_from_outside",
        190,
    ) {
        return;
    }
    // Two nodes composed in this "process", and an outside peer: another participant
    // with its own bus, as another process would be.
    let (inside, outside) = (composed(), composed());
    let (mut talker, mut listener, mut peer) = (
        node(&inside, "talker"),
        node(&inside, "listener"),
        node(&outside, "peer"),
    );
    let talk = talker.publisher::<StringMsg>("chatter").unwrap();
    let listen = listener.subscription::<StringMsg>("chatter").unwrap();
    let peer_listen = peer.subscription::<StringMsg>("chatter").unwrap();
    let peer_talk = peer.publisher::<StringMsg>("chatter").unwrap();

    // In-process delivery needs no discovery: the first message is there at once.
    talk.publish(text("first")).unwrap();
    assert_eq!(
        listen.take().unwrap().map(|(m, _)| m.data),
        Some("first".to_owned())
    );
    // Both directions over DDS matched, and the listener's reader has had time to match
    // the talker's writer too (same participant).
    until_heard(|m| talk.publish(m).unwrap(), &peer_listen, "probe in");
    until_heard(|m| peer_talk.publish(m).unwrap(), &listen, "probe out");
    std::thread::sleep(Duration::from_millis(500));
    drain(&listen, Duration::from_millis(300));
    drain(&peer_listen, Duration::from_millis(300));

    let ours: Vec<String> = (0..50).map(|k| format!("in {k}")).collect();
    let theirs: Vec<String> = (0..20).map(|k| format!("out {k}")).collect();
    // Taken as they come (the queues keep the last 10, as the QoS's history).
    let (mut got, mut peer_got) = (Vec::new(), Vec::new());
    for k in 0..50 {
        talk.publish(text(&ours[k])).unwrap();
        if k < 20 {
            peer_talk.publish(text(&theirs[k])).unwrap();
        }
        got.extend(drain(&listen, Duration::from_millis(5)));
        peer_got.extend(drain(&peer_listen, Duration::from_millis(5)));
    }
    got.extend(drain(&listen, Duration::from_secs(1)));
    peer_got.extend(drain(&peer_listen, Duration::from_secs(1)));
    let from = |prefix: &str| -> Vec<String> {
        got.iter()
            .filter(|m| m.starts_with(prefix))
            .cloned()
            .collect()
    };
    // Each once, in order: the DDS copy of the talker's messages is dropped.
    assert_eq!(from("in "), ours, "from the process: {got:?}");
    assert_eq!(from("out "), theirs, "from outside: {got:?}");
    // The outside peer gets the talker's messages through DDS, each once.
    let peer_in: Vec<String> = peer_got
        .iter()
        .filter(|m| m.starts_with("in "))
        .cloned()
        .collect();
    assert_eq!(peer_in, ours, "the outside peer: {peer_got:?}");
}

#[test]
fn a_late_latched_subscriber_in_the_process_gets_the_last_state_once() {
    if !in_private_network(
        "a_late_latched_subscriber_in_the_process_gets_the_last_state_once",
        191,
    ) {
        return;
    }
    let inside = composed();
    let mut owner = node(&inside, "owner");
    let state = owner.latched_publisher::<StringMsg>("state").unwrap();
    state.publish(text("state 1")).unwrap();
    state.publish(text("state 2")).unwrap();
    let mut late = node(&inside, "late");
    let sub = late.latched_subscription::<StringMsg>("state").unwrap();
    // Long enough for the DDS transient-local copy from the same participant to arrive too.
    std::thread::sleep(Duration::from_secs(2));
    assert_eq!(
        drain(&sub, Duration::from_millis(500)),
        vec!["state 2".to_owned()]
    );
    // Another type on the same name in the process is refused, naming the topic.
    let err = late
        .subscription::<biped_msgs::msg::BoolMsg>("state")
        .expect_err("String and Bool on one topic");
    assert!(format!("{err}").contains("topic `/state`"), "{err}");
}

/// An outside subscriber that joins after a composed publisher and its in-process
/// subscriber have been talking gets what is published from then on, once discovered, and
/// the in-process subscriber still gets each message once.
#[test]
fn an_outside_subscriber_that_joins_late_gets_a_composed_publisher_s_messages() {
    if !in_private_network(
        "an_outside_subscriber_that_joins_late_gets_a_composed_publisher_s_messages",
        193,
    ) {
        return;
    }
    let (inside, outside) = (composed(), composed());
    let (mut talker, mut listener) = (node(&inside, "talker"), node(&inside, "listener"));
    let talk = talker.publisher::<StringMsg>("news").unwrap();
    let listen = listener.subscription::<StringMsg>("news").unwrap();
    let mut got = Vec::new();
    for k in 0..20 {
        talk.publish(text(&format!("alone {k}"))).unwrap();
        got.extend(drain(&listen, Duration::from_millis(5)));
    }
    got.extend(drain(&listen, Duration::from_millis(500)));
    let alone: Vec<String> = (0..20).map(|k| format!("alone {k}")).collect();
    assert_eq!(got, alone, "in-process, each once");
    let mut peer = node(&outside, "peer");
    let peer_listen = peer.subscription::<StringMsg>("news").unwrap();
    until_heard(|m| talk.publish(m).unwrap(), &peer_listen, "anyone there");
    drain(&listen, Duration::from_millis(300));
    // From then on both get each message once.
    let (mut got, mut peer_got) = (Vec::new(), Vec::new());
    for k in 0..10 {
        talk.publish(text(&format!("both {k}"))).unwrap();
        got.extend(drain(&listen, Duration::from_millis(5)));
        peer_got.extend(drain(&peer_listen, Duration::from_millis(5)));
    }
    got.extend(drain(&listen, Duration::from_millis(500)));
    peer_got.extend(drain(&peer_listen, Duration::from_millis(500)));
    let both: Vec<String> = (0..10).map(|k| format!("both {k}")).collect();
    assert_eq!(got, both, "in-process");
    assert_eq!(peer_got, both, "outside");
}

/// A publisher counts the subscriptions that take its messages, in its process and outside
/// once discovered, as rclcpp's `get_subscription_count` does: what a node looks at before
/// building messages only viewers read (the planner's and the simulator's markers).
#[test]
fn a_publisher_counts_the_subscriptions_in_its_process_and_outside() {
    if !in_private_network(
        "a_publisher_counts_the_subscriptions_in_its_process_and_outside",
        231,
    ) {
        return;
    }
    let (inside, outside) = (composed(), composed());
    let mut talker = node(&inside, "talker");
    let talk = talker.publisher::<StringMsg>("views").unwrap();
    // The count of DDS subscriptions is kept by the node's spinner, on its executor.
    let spin = talker.executor().unwrap();
    let settled = |expected: usize| {
        let deadline = Instant::now() + Duration::from_secs(20);
        loop {
            while spin.try_tick() {}
            let n = talk.subscription_count(&talker);
            if n == expected {
                // Stays so while discovery goes on.
                for _ in 0..25 {
                    while spin.try_tick() {}
                    std::thread::sleep(Duration::from_millis(20));
                }
                return talk.subscription_count(&talker);
            }
            if Instant::now() > deadline {
                return n;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    };
    assert_eq!(settled(0), 0, "nobody yet");
    let mut listener = node(&inside, "listener");
    let listen = listener.subscription::<StringMsg>("views").unwrap();
    assert_eq!(settled(1), 1, "the subscriber in the process, once");
    let mut peer = node(&outside, "peer");
    let peer_listen = peer.subscription::<StringMsg>("views").unwrap();
    assert_eq!(settled(2), 2, "and the one outside, once discovered");
    drop(peer_listen);
    assert_eq!(settled(1), 1, "the one outside gone");
    drop(listen);
    assert_eq!(settled(0), 0, "both gone");
}
