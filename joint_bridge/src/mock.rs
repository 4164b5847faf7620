//! A backend with no hardware: what is written is what is read. For tests and dry runs.

use crate::backend::{Backend, BackendError, Lifecycle, Reading};
use crate::limits::JointSpec;

/// Copies commands into states (ros2_control's "mock components").
#[derive(Debug, Clone)]
pub struct MockBackend {
    state: Lifecycle,
    positions: Vec<f64>,
    /// Every write, in order (for tests): `(t_s, positions)`.
    pub writes: Vec<(f64, Vec<f64>)>,
    /// Keep at most this many writes in `writes`.
    pub keep_writes: usize,
}

impl Default for MockBackend {
    fn default() -> Self {
        Self {
            state: Lifecycle::Unconfigured,
            positions: Vec::new(),
            writes: Vec::new(),
            keep_writes: 0,
        }
    }
}

impl MockBackend {
    /// Its lifecycle state.
    pub fn state(&self) -> Lifecycle {
        self.state
    }
    fn refuse(&self, call: &'static str) -> BackendError {
        BackendError::State {
            backend: "mock".into(),
            call,
            state: self.state,
        }
    }
}

impl Backend for MockBackend {
    fn name(&self) -> &str {
        "mock"
    }
    fn configure(&mut self, joints: &[JointSpec]) -> Result<Option<Vec<f64>>, BackendError> {
        // Starts at zero (clamped into the limits): it has nothing to measure.
        self.positions = joints.iter().map(|j| j.clamp(0.0)).collect();
        self.state = Lifecycle::Inactive;
        Ok(None)
    }
    fn activate(&mut self) -> Result<(), BackendError> {
        match self.state {
            Lifecycle::Inactive | Lifecycle::Active => {
                self.state = Lifecycle::Active;
                Ok(())
            }
            _ => Err(self.refuse("activate")),
        }
    }
    fn write(&mut self, t_s: f64, positions_rad: &[f64]) -> Result<(), BackendError> {
        if self.state != Lifecycle::Active {
            return Err(self.refuse("write"));
        }
        if positions_rad.len() != self.positions.len() {
            return Err(BackendError::Io {
                backend: "mock".into(),
                why: format!(
                    "{} positions written for {} joints",
                    positions_rad.len(),
                    self.positions.len()
                ),
            });
        }
        self.positions.copy_from_slice(positions_rad);
        if self.keep_writes > 0 {
            if self.writes.len() >= self.keep_writes {
                self.writes.remove(0);
            }
            self.writes.push((t_s, positions_rad.to_vec()));
        }
        Ok(())
    }
    fn read(&mut self, _t_s: f64) -> Result<Reading, BackendError> {
        if self.state == Lifecycle::Unconfigured {
            return Err(self.refuse("read"));
        }
        Ok(Reading {
            positions_rad: self.positions.clone(),
            velocities_rad_s: None,
            measured: false,
        })
    }
    fn deactivate(&mut self) -> Result<(), BackendError> {
        if self.state != Lifecycle::Unconfigured {
            self.state = Lifecycle::Inactive;
        }
        Ok(())
    }
}
