//! The simulator as a joint_bridge [`Backend`]: the same lifecycle and calls as a serial
//! servo board, with the physics clock driven by the times the bridge passes in.
//!
//! | call | what the simulated robot does |
//! |---|---|
//! | `configure` | builds the simulator, stands the robot on the floor at the initial joint positions and lets it settle for `settle_s` with the servos holding them (the robot is placed on its feet); then torque off. Returns the measured positions. |
//! | `activate` | torque on, holding the joints where they are. |
//! | `write(t, q)` | physics up to `t`, then the new servo targets. |
//! | `read(t)` | physics up to `t`, then the measured positions and velocities (`measured: true`). |
//! | `deactivate` | torque off: the servos go limp (damping only), so a standing robot folds, as a real one would. |
//!
//! Time: the first `t` given to `write` or `read` is the end of the settling; later times
//! advance the physics by their difference. A time before the physics time is a no-op
//! (nothing is undone).

use joint_bridge::{Backend, BackendError, JointSpec, Lifecycle, Reading};

use std::path::PathBuf;

use crate::config::SimConfig;
use crate::mjcf::JointMap;
use crate::sim::Sim;

const NAME: &str = "sim";

/// A joint_bridge backend over a [`Sim`].
#[derive(Debug)]
pub struct SimBackend {
    urdf: String,
    cfg: SimConfig,
    scene: Option<(PathBuf, JointMap)>,
    initial_rad: Option<Vec<f64>>,
    sim: Option<Sim>,
    state: Lifecycle,
    /// Simulator joint of each configured joint.
    map: Vec<usize>,
    /// Bridge time that corresponds to the simulator's time `origin_sim_s`.
    origin: Option<f64>,
    origin_sim_s: f64,
}

impl SimBackend {
    /// A backend that will simulate the robot of `urdf` with `cfg`, standing at zero joint
    /// angles. Nothing is built before [`Backend::configure`].
    pub fn new(urdf: impl Into<String>, cfg: SimConfig) -> Self {
        Self {
            urdf: urdf.into(),
            cfg,
            scene: None,
            initial_rad: None,
            sim: None,
            state: Lifecycle::Unconfigured,
            map: Vec::new(),
            origin: None,
            origin_sim_s: 0.0,
        }
    }

    /// Stand at these joint positions (rad, [`ik_solver::RobotModel::dof_names`] order)
    /// instead of zeros.
    pub fn with_initial_positions(mut self, joints_rad: Vec<f64>) -> Self {
        self.initial_rad = Some(joints_rad);
        self
    }

    /// Simulate the MJCF scene at `path` instead of a model built from the URDF, its names
    /// tied to the URDF's by `map` (see [`Sim::from_mjcf_file`]).
    pub fn with_mjcf(mut self, path: impl Into<PathBuf>, map: JointMap) -> Self {
        self.scene = Some((path.into(), map));
        self
    }

    /// Its lifecycle state.
    pub fn state(&self) -> Lifecycle {
        self.state
    }

    /// The simulator, once configured: base pose, contacts, falls.
    pub fn sim(&self) -> Option<&Sim> {
        self.sim.as_ref()
    }

    fn refuse(&self, call: &'static str) -> BackendError {
        BackendError::State {
            backend: NAME.into(),
            call,
            state: self.state,
        }
    }

    fn io(why: impl ToString) -> BackendError {
        BackendError::Io {
            backend: NAME.into(),
            why: why.to_string(),
        }
    }

    /// Runs the physics up to bridge time `t_s`.
    fn advance(&mut self, t_s: f64) -> Result<(), BackendError> {
        if !t_s.is_finite() {
            return Err(Self::io(format!("time {t_s} s is not finite")));
        }
        let origin = *self.origin.get_or_insert(t_s);
        let Some(sim) = self.sim.as_mut() else {
            return Err(self.refuse("advance"));
        };
        let target = self.origin_sim_s + (t_s - origin);
        if target > sim.time_s() {
            sim.advance_to(target).map_err(Self::io)?;
        }
        Ok(())
    }
}

impl Backend for SimBackend {
    fn name(&self) -> &str {
        NAME
    }

    fn configure(&mut self, joints: &[JointSpec]) -> Result<Option<Vec<f64>>, BackendError> {
        let open = |why: String| BackendError::Open {
            backend: NAME.into(),
            why,
        };
        let built = match &self.scene {
            Some((path, map)) => Sim::from_mjcf_file(path, map, &self.urdf, None, &self.cfg),
            None => Sim::from_urdf_str(&self.urdf, None, &self.cfg),
        };
        let mut sim = built.map_err(|e| open(e.to_string()))?;
        let mut map = Vec::with_capacity(joints.len());
        for j in joints {
            let i = sim
                .joint_names()
                .iter()
                .position(|n| *n == j.name)
                .ok_or_else(|| BackendError::Joint {
                    backend: NAME.into(),
                    joint: j.name.clone(),
                    why: "not a movable joint of the simulated robot".into(),
                })?;
            map.push(i);
        }
        let initial = self
            .initial_rad
            .clone()
            .unwrap_or_else(|| vec![0.0; sim.joint_names().len()]);
        sim.stand(&initial).map_err(|e| open(e.to_string()))?;
        sim.step(sim.config().settle_s)
            .map_err(|e| open(e.to_string()))?;
        sim.set_torque(false);
        let q = sim.joint_positions_rad();
        let measured = map.iter().map(|&i| q[i]).collect();
        self.origin_sim_s = sim.time_s();
        self.origin = None;
        self.sim = Some(sim);
        self.map = map;
        self.state = Lifecycle::Inactive;
        Ok(Some(measured))
    }

    fn activate(&mut self) -> Result<(), BackendError> {
        match (self.state, self.sim.as_mut()) {
            (Lifecycle::Inactive | Lifecycle::Active, Some(sim)) => {
                if self.state == Lifecycle::Inactive {
                    let here = sim.joint_positions_rad();
                    sim.set_targets(&here).map_err(Self::io)?;
                    sim.set_torque(true);
                }
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
        if positions_rad.len() != self.map.len() {
            return Err(Self::io(format!(
                "{} positions written for {} joints",
                positions_rad.len(),
                self.map.len()
            )));
        }
        self.advance(t_s)?;
        let Some(sim) = self.sim.as_mut() else {
            return Err(self.refuse("write"));
        };
        let mut targets = sim.targets_rad().to_vec();
        for (&i, &v) in self.map.iter().zip(positions_rad) {
            targets[i] = v;
        }
        sim.set_targets(&targets).map_err(|e| match e {
            crate::SimError::NonFinite { joint, value, .. } => BackendError::Joint {
                backend: NAME.into(),
                joint,
                why: format!("target {value} rad is not finite"),
            },
            other => Self::io(other),
        })
    }

    fn read(&mut self, t_s: f64) -> Result<Reading, BackendError> {
        if self.state == Lifecycle::Unconfigured {
            return Err(self.refuse("read"));
        }
        self.advance(t_s)?;
        let Some(sim) = self.sim.as_ref() else {
            return Err(self.refuse("read"));
        };
        let (q, v) = (sim.joint_positions_rad(), sim.joint_velocities_rad_s());
        Ok(Reading {
            positions_rad: self.map.iter().map(|&i| q[i]).collect(),
            velocities_rad_s: Some(self.map.iter().map(|&i| v[i]).collect()),
            measured: true,
        })
    }

    fn deactivate(&mut self) -> Result<(), BackendError> {
        if let Some(sim) = self.sim.as_mut() {
            sim.set_torque(false);
        }
        if self.state != Lifecycle::Unconfigured {
            self.state = Lifecycle::Inactive;
        }
        Ok(())
    }
}
