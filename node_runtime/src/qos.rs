//! QoS profiles of the fleet's topics.

use ros2_client::QosProfile;
use ros2_client::qos::{Durability, History, Reliability, WhenFull};

/// rclpy's default for publishers and subscriptions (depth 10): reliable, volatile,
/// keep last 10. Used for every command and state topic, as ROS tools expect.
pub fn default() -> QosProfile {
    QosProfile::publisher_default()
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 10 })
}

/// What the fleet's publishers use: [`default`] as the other side sees it (reliable,
/// volatile; keep last 100), and a full send window fails the publish at once instead of
/// waiting: the control loop never waits on a subscriber. The window is RustDDS's, 8 192
/// unacknowledged samples (the depth does not set it: `patches/rustdds`, `pubsub.rs`), 82 s
/// at 100 Hz: a subscriber that stops acknowledging for longer (its process stopped or
/// hung) makes every publish on the topic fail, for every subscriber, until it
/// acknowledges again or its participant is declared gone when its lease runs out.
pub fn publisher() -> QosProfile {
    default()
        .history(History::KeepLast { depth: 100 })
        .reliability(Reliability::Reliable {
            when_full: WhenFull::Fail,
        })
}

/// Latched state (`robot_description`, `/tf_static`): reliable, transient local, keep last
/// 1, as robot_state_publisher and tf2's static broadcaster offer it: a subscriber that
/// joins later, with transient local durability, still gets the last message.
pub fn latched() -> QosProfile {
    QosProfile::publisher_default()
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 1 })
        .reliability(Reliability::Reliable {
            when_full: WhenFull::Fail,
        })
}

/// `/clock` as a node reads it: best effort (rclcpp's `ClockQoS`, what `ros2 bag play
/// --clock` and most simulators publish), which a reliable `/clock` also matches; keep last
/// 100 so a node that falls behind still sees every tick it can catch up on.
pub fn clock() -> QosProfile {
    default()
        .history(History::KeepLast { depth: 100 })
        .reliability(Reliability::BestEffort)
}

/// Services (requests and responses): ROS's service default, reliable, volatile, keep last 10.
pub fn service() -> QosProfile {
    default()
}
