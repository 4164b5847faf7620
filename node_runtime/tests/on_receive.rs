//! A subscription handled on the DDS thread that receives its messages
//! ([`node_runtime::Subscription::on_receive`]): every message, in order, on that thread;
//! nothing after the handle is dropped; a handler that panics is dropped and the node's
//! participant goes on; refused for composed nodes; a node served that way
//! ([`node_runtime::RosNode::serve_on_receive`]) ends with an error naming the topic when its
//! handler panics. Each test re-runs itself in a private network namespace with only
//! loopback (root), on its own ROS_DOMAIN_ID (227-230).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::ThreadId;
use std::time::{Duration, Instant};

use biped_msgs::msg::StringMsg;
use common::{in_private_network, node, text, until_heard};
use node_runtime::{Host, OnReceive, Publisher, RosError, RosNode, Said};

type Record = Arc<Mutex<Vec<(String, ThreadId)>>>;

/// Publishes `probe` every 100 ms until `record` has it (the handler's reader has matched).
fn until_recorded(publish: impl Fn(&str), record: &Record, probe: &str) {
    let deadline = Instant::now() + Duration::from_secs(30);
    while !record.lock().unwrap().iter().any(|(m, _)| m == probe) {
        assert!(
            Instant::now() < deadline,
            "`{probe}` not handled within 30 s"
        );
        publish(probe);
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// A listener alone in its "process" whose `chatter` is handled on its DDS thread, recording
/// each message and the thread it ran on (panicking on `panic_on`), and a talker on another
/// participant (composed, so that the test needs no second process: `Host::process` is once
/// per process), once the handler has had the talker's probe.
fn listening(
    panic_on: &'static str,
) -> (
    RosNode,
    RosNode,
    Publisher<StringMsg>,
    Record,
    OnReceive<StringMsg>,
) {
    let (here, there) = (
        Host::process().unwrap(),
        Host::composed(Arc::new(AtomicBool::new(false))).unwrap(),
    );
    let (mut listener, mut talker) = (node(&here, "listener"), node(&there, "talker"));
    let talk = talker.publisher::<StringMsg>("chatter").unwrap();
    let record: Record = Arc::default();
    let into = Arc::clone(&record);
    let handle = listener
        .subscription::<StringMsg>("chatter")
        .unwrap()
        .on_receive(move |received| {
            let (m, _) = received.unwrap();
            assert!(m.data != panic_on, "the handler's panic");
            into.lock()
                .unwrap()
                .push((m.data, std::thread::current().id()));
        })
        .unwrap();
    until_recorded(|p| talk.publish(text(p)).unwrap(), &record, "probe");
    (listener, talker, talk, record, handle)
}

#[test]
fn a_subscription_handled_on_its_dds_thread_gets_every_message_in_order_there() {
    if !in_private_network(
        "a_subscription_handled_on_its_dds_thread_gets_every_message_in_order_there",
        227,
    ) {
        return;
    }
    let (_listener, _talker, talk, record, handle) = listening("");

    // Keep last 10 on the reader: a node thread taking them late would lose all but the
    // last 10 of a burst; taken as each arrives, none is lost.
    let sent: Vec<String> = (0..200).map(|k| format!("m {k}")).collect();
    for m in &sent {
        talk.publish(text(m)).unwrap();
        std::thread::sleep(Duration::from_millis(1));
    }
    // (Without the probes: one published before the match may still come.)
    let burst = || -> Vec<(String, ThreadId)> {
        let record = record.lock().unwrap();
        record
            .iter()
            .filter(|(m, _)| m != "probe")
            .cloned()
            .collect()
    };
    let deadline = Instant::now() + Duration::from_secs(30);
    while burst().len() < sent.len() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
    }
    let got = burst();
    let texts: Vec<&String> = got.iter().map(|(m, _)| m).collect();
    assert_eq!(texts, sent.iter().collect::<Vec<_>>());
    let here_thread = std::thread::current().id();
    assert!(
        got.iter().all(|(_, t)| *t != here_thread),
        "a message was handled on the test's thread, not on the DDS thread"
    );
    assert!(!handle.failed());

    // Dropped: the handler (and what it holds) is gone.
    drop(handle);
    assert_eq!(
        Arc::strong_count(&record),
        1,
        "the handler was kept after its handle was dropped"
    );
}

#[test]
fn a_handler_that_panics_is_dropped_and_its_participant_goes_on() {
    if !in_private_network(
        "a_handler_that_panics_is_dropped_and_its_participant_goes_on",
        228,
    ) {
        return;
    }
    let (mut listener, mut talker, talk, record, handle) = listening("boom");
    talk.publish(text("boom")).unwrap();
    let deadline = Instant::now() + Duration::from_secs(30);
    while !handle.failed() {
        assert!(
            Instant::now() < deadline,
            "the panic was not noticed within 30 s"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    assert_eq!(
        Arc::strong_count(&record),
        1,
        "the handler was kept after it panicked"
    );
    // The participant's DDS thread survived the panic: another subscription of the node
    // still gets the talker's messages.
    let other = listener.subscription::<StringMsg>("other").unwrap();
    let talk_other = talker.publisher::<StringMsg>("other").unwrap();
    until_heard(|m| talk_other.publish(m).unwrap(), &other, "still here");
}

#[test]
fn a_composed_node_s_subscription_is_not_handled_on_a_dds_thread() {
    if !in_private_network(
        "a_composed_node_s_subscription_is_not_handled_on_a_dds_thread",
        229,
    ) {
        return;
    }
    let host = Host::composed(Arc::new(AtomicBool::new(false))).unwrap();
    let mut listener = node(&host, "listener");
    let refused = listener
        .subscription::<StringMsg>("chatter")
        .unwrap()
        .on_receive(|_| {})
        .unwrap_err()
        .to_string();
    assert!(
        refused.contains("std_msgs/msg/String") && refused.contains("composed"),
        "{refused}"
    );
}

#[test]
fn a_node_served_on_receive_ends_with_an_error_naming_the_topic_when_its_handler_panics() {
    if !in_private_network(
        "a_node_served_on_receive_ends_with_an_error_naming_the_topic_when_its_handler_panics",
        230,
    ) {
        return;
    }
    let (here, there) = (
        Host::process().unwrap(),
        Host::composed(Arc::new(AtomicBool::new(false))).unwrap(),
    );
    let (mut listener, mut talker) = (node(&here, "listener"), node(&there, "talker"));
    let talk = talker.publisher::<StringMsg>("chatter").unwrap();
    let sub = listener.subscription::<StringMsg>("chatter").unwrap();
    // The talker says "probe" until the handler has had one, then "boom"; the stop flag is
    // the test's own bound (set after 30 s, it would end the serving without an error).
    let stop = Arc::new(AtomicBool::new(false));
    let heard = Arc::new(AtomicBool::new(false));
    let talking = {
        let (stop, heard) = (Arc::clone(&stop), Arc::clone(&heard));
        std::thread::spawn(move || {
            let deadline = Instant::now() + Duration::from_secs(30);
            while Instant::now() < deadline && !stop.load(Ordering::SeqCst) {
                let say = if heard.load(Ordering::SeqCst) {
                    "boom"
                } else {
                    "probe"
                };
                talk.publish(text(say)).unwrap();
                std::thread::sleep(Duration::from_millis(50));
            }
            stop.store(true, Ordering::SeqCst);
        })
    };
    let handled = Arc::new(Mutex::new(Vec::<String>::new()));
    let into = Arc::clone(&handled);
    let served = smol::block_on(listener.serve_on_receive(
        sub,
        "chatter",
        &stop,
        move |m: StringMsg, say: &mut dyn FnMut(Said)| {
            assert!(m.data != "boom", "the handler's panic");
            say(Said::Warn(format!("handled {}", m.data)));
            into.lock().unwrap().push(m.data);
            heard.store(true, Ordering::SeqCst);
        },
    ));
    stop.store(true, Ordering::SeqCst);
    talking.join().unwrap();
    match served {
        Err(RosError::HandlerPanicked { topic }) => assert_eq!(topic, "chatter"),
        other => panic!("served until the stop flag, not ended by the panic: {other:?}"),
    }
    assert_eq!(
        Arc::strong_count(&handled),
        1,
        "the handler was kept after it panicked"
    );
    let handled = handled.lock().unwrap();
    assert!(handled.iter().any(|m| m == "probe"), "{handled:?}");
    assert!(!handled.iter().any(|m| m == "boom"), "{handled:?}");
}
