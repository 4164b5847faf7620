//! Logging to the console (stderr) and `/rosout` at once, with `--log-level`.

use ros2_client::Node;
use ros2_client::ros2::LogLevel;
use ros2_client::rosout;

use crate::args::RosArgs;

/// Logging to the console (stderr) and `/rosout` at once.
#[derive(Debug, Clone)]
pub struct Log {
    /// The node's fully qualified name, for the console.
    pub node: String,
    /// Least level printed and sent.
    pub min_level: LogLevel,
}

fn level_rank(l: LogLevel) -> u8 {
    match l {
        LogLevel::Debug => 0,
        LogLevel::Info => 1,
        LogLevel::Warn => 2,
        LogLevel::Error => 3,
        LogLevel::Fatal => 4,
    }
}

impl Log {
    /// For a node; `--log-level` (debug, info, warn, error) sets the least level.
    pub fn new(node: &Node, args: &RosArgs) -> Self {
        let min_level = match args
            .log_level
            .as_deref()
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("debug") => LogLevel::Debug,
            Some("warn") => LogLevel::Warn,
            Some("error") => LogLevel::Error,
            Some("fatal") => LogLevel::Fatal,
            _ => LogLevel::Info,
        };
        Self {
            node: node.fully_qualified_name(),
            min_level,
        }
    }
    /// Logs a line.
    pub fn log(&self, node: &Node, level: LogLevel, msg: &str) {
        if level_rank(level) < level_rank(self.min_level) {
            return;
        }
        let tag = match level {
            LogLevel::Debug => "DEBUG",
            LogLevel::Info => "INFO",
            LogLevel::Warn => "WARN",
            LogLevel::Error => "ERROR",
            LogLevel::Fatal => "FATAL",
        };
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default();
        eprintln!(
            "[{tag}] [{}.{:09}] [{}]: {msg}",
            now.as_secs(),
            now.subsec_nanos(),
            self.node
        );
        rosout!(*node, level, "{msg}");
    }
    /// Info.
    pub fn info(&self, node: &Node, msg: &str) {
        self.log(node, LogLevel::Info, msg);
    }
    /// Warning.
    pub fn warn(&self, node: &Node, msg: &str) {
        self.log(node, LogLevel::Warn, msg);
    }
    /// Error.
    pub fn error(&self, node: &Node, msg: &str) {
        self.log(node, LogLevel::Error, msg);
    }
}

/// Repeated messages logged at most once a `period` per key (a topic, a device), each logged
/// one saying how many of its key were held back since the last logged: a fault repeated
/// every control tick shows once a second, and one key's fault never hides another's. Time
/// is passed in.
#[derive(Debug)]
pub struct Throttle {
    period: std::time::Duration,
    /// Per key: when its last message was logged, and how many were held back since.
    last: std::collections::BTreeMap<String, (std::time::Instant, u64)>,
}

impl Throttle {
    /// Once a `period` per key.
    pub fn new(period: std::time::Duration) -> Self {
        Self {
            period,
            last: std::collections::BTreeMap::new(),
        }
    }

    /// The line to log for `msg` of `key` at `now`: `msg` itself, with the count of the
    /// key's messages held back since its last logged one if any; `None` if held back.
    pub fn admit(&mut self, key: &str, msg: &str, now: std::time::Instant) -> Option<String> {
        match self.last.get_mut(key) {
            Some((last, held)) if now.saturating_duration_since(*last) < self.period => {
                *held += 1;
                None
            }
            Some(entry) => {
                let held = std::mem::replace(entry, (now, 0)).1;
                Some(if held > 0 {
                    format!("{msg} ({held} more like it held back since the last logged)")
                } else {
                    msg.to_owned()
                })
            }
            None => {
                self.last.insert(key.to_owned(), (now, 0));
                Some(msg.to_owned())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use std::time::{Duration, Instant};

    use super::Throttle;

    #[test]
    fn a_throttle_holds_back_repeats_per_key_and_counts_them() {
        let t0 = Instant::now();
        let ms = |n: u64| t0 + Duration::from_millis(n);
        let mut t = Throttle::new(Duration::from_secs(1));
        assert_eq!(
            t.admit("publish imu/data", "a", ms(0)).as_deref(),
            Some("a")
        );
        // Every 10 ms for the rest of the second: held back, counted.
        for n in 1..100 {
            assert_eq!(t.admit("publish imu/data", "a", ms(10 * n)), None);
        }
        // Another key's first message, inside the same second: logged.
        assert_eq!(
            t.admit("publish /clock", "b", ms(500)).as_deref(),
            Some("b")
        );
        assert_eq!(t.admit("publish /clock", "b", ms(600)), None);
        // A second after the first: logged with the 99 held back, then the count restarts.
        assert_eq!(
            t.admit("publish imu/data", "a", ms(1000)).as_deref(),
            Some("a (99 more like it held back since the last logged)")
        );
        assert_eq!(t.admit("publish imu/data", "a", ms(1500)), None);
        assert_eq!(
            t.admit("publish imu/data", "a", ms(2000)).as_deref(),
            Some("a (1 more like it held back since the last logged)")
        );
        // The other key's second is over at 1.5 s: its one held back message is counted.
        assert_eq!(
            t.admit("publish /clock", "c", ms(1500)).as_deref(),
            Some("c (1 more like it held back since the last logged)")
        );
        // Nothing held back since: the plain message.
        assert_eq!(
            t.admit("publish /clock", "c", ms(2600)).as_deref(),
            Some("c")
        );
    }
}
