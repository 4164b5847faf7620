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
