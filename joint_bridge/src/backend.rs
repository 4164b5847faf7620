//! The one contract every backend (mock, simulator, serial boards) implements.

use crate::limits::JointSpec;

/// Where a backend is in its lifecycle (as ros2_control's hardware components).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lifecycle {
    /// Created; nothing opened.
    Unconfigured,
    /// Configured: the device is open and may be read, but must not move (torque off).
    Inactive,
    /// Active: torque on, commands are written.
    Active,
    /// A fault stopped it; torque is off.
    Error,
}

/// What a backend reports back.
#[derive(Debug, Clone, PartialEq)]
pub struct Reading {
    /// Joint positions (rad), in the configured joint order.
    pub positions_rad: Vec<f64>,
    /// Joint velocities (rad/s), when the backend knows them.
    pub velocities_rad_s: Option<Vec<f64>>,
    /// True when the positions are measured; false when they are the commanded ones.
    pub measured: bool,
}

/// A backend failure, naming the device or joint.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BackendError {
    /// The device could not be opened or found.
    #[error("{backend}: cannot open: {why}")]
    Open {
        /// The backend.
        backend: String,
        /// Why.
        why: String,
    },
    /// A joint the backend cannot drive.
    #[error("{backend}: joint `{joint}`: {why}")]
    Joint {
        /// The backend.
        backend: String,
        /// The joint.
        joint: String,
        /// Why.
        why: String,
    },
    /// An I/O or protocol failure while running.
    #[error("{backend}: {why}")]
    Io {
        /// The backend.
        backend: String,
        /// Why.
        why: String,
    },
    /// A call in the wrong lifecycle state.
    #[error("{backend}: {call} is not allowed while {state:?}")]
    State {
        /// The backend.
        backend: String,
        /// The call.
        call: &'static str,
        /// The state it was in.
        state: Lifecycle,
    },
}

/// How healthy a backend is (the levels of diagnostic_msgs/DiagnosticStatus).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DiagnosticLevel {
    /// Working.
    #[default]
    Ok,
    /// Working, with something to look at.
    Warn,
    /// Not working.
    Error,
}

impl DiagnosticLevel {
    /// The `level` byte of diagnostic_msgs/DiagnosticStatus.
    pub fn as_byte(self) -> u8 {
        match self {
            DiagnosticLevel::Ok => 0,
            DiagnosticLevel::Warn => 1,
            DiagnosticLevel::Error => 2,
        }
    }
}

/// A backend's health and counters, for the node to publish on `/diagnostics`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Diagnostics {
    /// What is reported on ("joint_bridge: dynamixel2 board").
    pub name: String,
    /// The device (serial port).
    pub hardware_id: String,
    /// Health.
    pub level: DiagnosticLevel,
    /// One line.
    pub message: String,
    /// Counters and details, as key and value.
    pub values: Vec<(String, String)>,
}

/// A joint-level hardware or simulator interface with a lifecycle:
/// `configure` (open, may read, must not move) → `activate` (torque on) → `write`/`read` →
/// `deactivate` (torque off; also on shutdown, watchdog and errors).
pub trait Backend: Send {
    /// A short name for logs ("mock", "sim", "dynamixel2", ...).
    fn name(&self) -> &str;
    /// Opens the device for these joints. Returns the measured positions (rad) where the
    /// backend can read them.
    fn configure(&mut self, joints: &[JointSpec]) -> Result<Option<Vec<f64>>, BackendError>;
    /// Torque on: from now on the joints hold the positions written.
    fn activate(&mut self) -> Result<(), BackendError>;
    /// Sends goal positions (rad), one per configured joint, at time `t_s`.
    fn write(&mut self, t_s: f64, positions_rad: &[f64]) -> Result<(), BackendError>;
    /// Reads the joint states at time `t_s`.
    fn read(&mut self, t_s: f64) -> Result<Reading, BackendError>;
    /// Torque off. Must be safe to call in any state and more than once.
    fn deactivate(&mut self) -> Result<(), BackendError>;
    /// Health and counters, for backends that have some.
    fn diagnostics(&self) -> Option<Diagnostics> {
        None
    }
    /// Things noticed since the last call, for the log (e.g. a servo's error bits by name).
    fn take_notices(&mut self) -> Vec<String> {
        Vec::new()
    }
    /// For a backend that cannot measure (`configure` returned no positions): the pose
    /// (rad) its first writes start from, the robot's configured rest pose, which the
    /// device moves to at its own configured slow speed. `None`: no such pose.
    fn start_pose(&self) -> Option<Vec<f64>> {
        None
    }
}

/// A boxed backend is a backend (the node picks one at run time).
impl<B: Backend + ?Sized> Backend for Box<B> {
    fn name(&self) -> &str {
        (**self).name()
    }
    fn configure(&mut self, joints: &[JointSpec]) -> Result<Option<Vec<f64>>, BackendError> {
        (**self).configure(joints)
    }
    fn activate(&mut self) -> Result<(), BackendError> {
        (**self).activate()
    }
    fn write(&mut self, t_s: f64, positions_rad: &[f64]) -> Result<(), BackendError> {
        (**self).write(t_s, positions_rad)
    }
    fn read(&mut self, t_s: f64) -> Result<Reading, BackendError> {
        (**self).read(t_s)
    }
    fn deactivate(&mut self) -> Result<(), BackendError> {
        (**self).deactivate()
    }
    fn diagnostics(&self) -> Option<Diagnostics> {
        (**self).diagnostics()
    }
    fn take_notices(&mut self) -> Vec<String> {
        (**self).take_notices()
    }
    fn start_pose(&self) -> Option<Vec<f64>> {
        (**self).start_pose()
    }
}
