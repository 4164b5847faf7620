//! The simulated robot: MuJoCo physics behind a small API in the robot's own terms (joint
//! vectors in [`ik_solver::RobotModel::dof_names`] order, nalgebra poses, seconds).

use std::fmt;
use std::sync::Arc;

use ik_solver::support::{Xy, convex_hull, signed_margin};
use ik_solver::{BipedModel, LegRoleMap, Side, StaticPose};
use mujoco_rs::prelude::*;
use nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion, Vector3};

use crate::compensation::static_foot_loads;
use crate::config::SimConfig;
use crate::error::SimError;
use crate::mjcf::{self, JointMap};
use crate::mjmodel::{self, Layout};

/// A sole counts as loaded (part of the support polygon) above this share of the weight.
pub const LOADED_FRACTION: f64 = 0.01;
/// The centre of pressure is defined when the floor carries at least this share of the weight.
pub const COP_MIN_FRACTION: f64 = 0.1;
/// More than this share of the weight on anything but the soles is a fall.
pub const BODY_CONTACT_FRACTION: f64 = 0.05;

/// An inertial measurement unit at the base link's origin ([`Sim::imu`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuReading {
    /// The base's orientation in the world.
    pub orientation: UnitQuaternion<f64>,
    /// The base's angular velocity in its own frame (rad/s): what a gyroscope reads.
    pub angular_velocity_rad_s: Vector3<f64>,
    /// Acceleration less gravity in the base's frame (m/s²): what an accelerometer reads
    /// (+9.81 along the base's z standing level, 0 falling freely).
    pub specific_force_m_s2: Vector3<f64>,
}

/// Angle between a pose's z axis and the world's (rad): the base's tilt from upright.
pub fn tilt_rad(pose: &Isometry3<f64>) -> f64 {
    let z = pose.rotation * Vector3::z();
    z.z.clamp(-1.0, 1.0).acos()
}

/// Why the robot is considered fallen.
#[derive(Debug, Clone, PartialEq)]
pub enum FallReason {
    /// The base tilted beyond `fall_tilt_deg`.
    Tilt {
        /// Tilt from upright (deg).
        tilt_deg: f64,
    },
    /// The base dropped more than `fall_height_drop_m` below its starting height.
    Dropped {
        /// How far below (m).
        drop_m: f64,
    },
    /// Something other than a sole pressed on the floor.
    BodyContact {
        /// The body.
        body: String,
        /// Its floor force (N).
        force_n: f64,
    },
}

impl fmt::Display for FallReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FallReason::Tilt { tilt_deg } => write!(f, "base tilted {tilt_deg:.1} deg"),
            FallReason::Dropped { drop_m } => write!(f, "base dropped {drop_m:.3} m"),
            FallReason::BodyContact { body, force_n } => {
                write!(f, "`{body}` touches the floor ({force_n:.2} N)")
            }
        }
    }
}

/// The first fall seen since the last reset.
#[derive(Debug, Clone, PartialEq)]
pub struct Fall {
    /// Simulation time (s).
    pub t_s: f64,
    /// Why.
    pub reason: FallReason,
}

/// Floor contact forces at one instant.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactReading {
    /// Sum of the normal forces of all floor contacts (N).
    pub normal_force_sum_n: f64,
    /// Normal force on each sole, `[left, right]` (N).
    pub sole_force_n: [f64; 2],
    /// Normal force on anything else touching the floor (N).
    pub other_force_n: f64,
    /// The body (URDF link name; fused static links take their parent's) carrying most of
    /// `other_force_n`, if any.
    pub other_body: Option<String>,
    /// Centre of pressure on the floor (world x, y, m): the force-weighted mean of the floor
    /// contact points; `None` when the floor carries less than [`COP_MIN_FRACTION`] of the
    /// weight.
    pub cop_world_m: Option<Xy>,
    /// Soles carrying more than [`LOADED_FRACTION`] of the weight, `[left, right]`.
    pub loaded: [bool; 2],
    /// Support polygon: the convex hull of the loaded soles' footprints (world x, y, m,
    /// counter-clockwise); empty when no sole is loaded.
    pub support_polygon: Vec<Xy>,
}

impl ContactReading {
    /// Signed distance of the centre of pressure to the support polygon's edge (m), positive
    /// inside; `None` without a centre of pressure.
    pub fn cop_margin_m(&self) -> Option<f64> {
        self.cop_world_m
            .map(|p| signed_margin(&self.support_polygon, p))
    }
}

/// The biped in MuJoCo, driven by position servos.
///
/// Time advances only in [`Sim::step`] / [`Sim::advance_to`], in whole physics steps.
/// Readings after a step: joint and base positions are those at the end of the step;
/// contact forces (and body positions used with them) are those the step computed, at its
/// start: at most one `timestep_s` old.
///
/// ```
/// # fn main() -> Result<(), sim_bridge::SimError> {
/// let mut sim = sim_bridge::Sim::from_urdf_str(ik_solver::DEFAULT_URDF, None, &Default::default())?;
/// let zeros = vec![0.0; sim.joint_names().len()];
/// sim.stand(&zeros)?;
/// sim.step(1.0)?;
/// assert!(sim.fallen().is_none());
/// # Ok(()) }
/// ```
#[derive(Debug, Clone)]
pub struct Sim {
    data: MjData<Arc<MjModel>>,
    layout: Layout,
    cfg: SimConfig,
    biped: BipedModel,
    targets_rad: Vec<f64>,
    torque_on: bool,
    steps: u64,
    reference_base_z_m: f64,
    fall: Option<Fall>,
    weight_n: f64,
    total_mass_kg: f64,
    bad_qacc_warnings: i32,
}

fn finite_joints(names: &[String], what: &'static str, v: &[f64]) -> Result<(), SimError> {
    if v.len() != names.len() {
        return Err(SimError::JointCount {
            what,
            expected: names.len(),
            got: v.len(),
        });
    }
    if let Some((i, &value)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
        return Err(SimError::NonFinite {
            joint: names[i].clone(),
            what,
            value,
        });
    }
    Ok(())
}

impl Sim {
    /// Builds the simulator of the robot in `urdf` (a URDF document; it is parsed from the
    /// string, so mesh files it names are not found: use primitive collision shapes), finding
    /// its legs by their axes or from `role_map`. Starts at t = 0 with the base at the world
    /// origin and the joints at 0, servos on: call [`Self::reset`] or [`Self::stand`] to put
    /// the robot on the floor before stepping.
    pub fn from_urdf_str(
        urdf: &str,
        role_map: Option<&LegRoleMap>,
        cfg: &SimConfig,
    ) -> Result<Self, SimError> {
        cfg.validate()?;
        let biped = BipedModel::from_urdf_str(urdf, role_map)?;
        let (model, layout) = mjmodel::build(urdf, &biped, cfg)?;
        Self::with_model(model, layout, cfg.clone(), biped)
    }

    /// Builds the simulator of a given MJCF scene (`mjcf`: the XML text; files it names are
    /// not found, use [`Self::from_mjcf_file`] for a scene with meshes or includes) whose
    /// robot is the one of `urdf`, its names tied by `map` (see [`crate::JointMap`]). The
    /// URDF gives the robot model of the plans and the sag compensation; the scene gives
    /// the physics: [`Self::config`] then holds the scene's servo gains, timestep and sole
    /// friction, `cfg` only its fall bounds and `settle_s`. Starts as
    /// [`Self::from_urdf_str`] does, with the scene's initial pose.
    pub fn from_mjcf_str(
        mjcf: &str,
        map: &JointMap,
        urdf: &str,
        role_map: Option<&LegRoleMap>,
        cfg: &SimConfig,
    ) -> Result<Self, SimError> {
        Self::from_mjcf(mjcf::Source::Text(mjcf), map, urdf, role_map, cfg)
    }

    /// [`Self::from_mjcf_str`] with the scene read from a file (meshes and includes found
    /// relative to it).
    pub fn from_mjcf_file(
        path: impl AsRef<std::path::Path>,
        map: &JointMap,
        urdf: &str,
        role_map: Option<&LegRoleMap>,
        cfg: &SimConfig,
    ) -> Result<Self, SimError> {
        Self::from_mjcf(mjcf::Source::File(path.as_ref()), map, urdf, role_map, cfg)
    }

    fn from_mjcf(
        source: mjcf::Source<'_>,
        map: &JointMap,
        urdf: &str,
        role_map: Option<&LegRoleMap>,
        cfg: &SimConfig,
    ) -> Result<Self, SimError> {
        cfg.validate()?;
        let biped = BipedModel::from_urdf_str(urdf, role_map)?;
        let (model, layout, effective) = mjcf::load(source, map, &biped, cfg)?;
        Self::with_model(model, layout, effective, biped)
    }

    fn with_model(
        model: Arc<MjModel>,
        layout: Layout,
        cfg: SimConfig,
        biped: BipedModel,
    ) -> Result<Self, SimError> {
        let total_mass_kg = model.body_subtreemass()[0];
        let gravity = model.opt().gravity;
        let weight_n = total_mass_kg * Vector3::from(gravity).norm();
        let data = MjData::try_new(model).map_err(|e| SimError::Mujoco {
            stage: "allocate data for",
            message: e.to_string(),
        })?;
        let n = layout.dof_names.len();
        let mut sim = Self {
            data,
            layout,
            cfg,
            biped,
            targets_rad: vec![0.0; n],
            torque_on: true,
            steps: 0,
            reference_base_z_m: 0.0,
            fall: None,
            weight_n,
            total_mass_kg,
            bad_qacc_warnings: 0,
        };
        sim.data.forward();
        sim.reference_base_z_m = sim.base_pose().translation.z;
        Ok(sim)
    }

    /// The robot model the simulator was built from.
    pub fn biped(&self) -> &BipedModel {
        &self.biped
    }
    /// The settings.
    pub fn config(&self) -> &SimConfig {
        &self.cfg
    }
    /// Movable joints, in the order of every joint vector here.
    pub fn joint_names(&self) -> &[String] {
        &self.layout.dof_names
    }
    /// Warnings MuJoCo gave while compiling the model.
    pub fn build_warnings(&self) -> &[String] {
        &self.layout.warnings
    }
    /// Total mass of the simulated robot (kg).
    pub fn total_mass_kg(&self) -> f64 {
        self.total_mass_kg
    }
    /// Its weight (N).
    pub fn weight_n(&self) -> f64 {
        self.weight_n
    }
    /// Simulation time (s): physics steps taken since the last reset × `timestep_s`.
    pub fn time_s(&self) -> f64 {
        self.steps as f64 * self.cfg.timestep_s
    }
    /// Physics steps since the last reset.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Starts over at t = 0 from a pose, at rest: the base (root link) at `base` in the world
    /// (floor at z = 0), the joints at `joints_rad`; the servo targets are set to the same
    /// joint positions and the servos are on. The base height is the reference for the fall
    /// check.
    pub fn reset(&mut self, base: &Isometry3<f64>, joints_rad: &[f64]) -> Result<(), SimError> {
        finite_joints(&self.layout.dof_names, "position", joints_rad)?;
        let t = base.translation.vector;
        let q = base.rotation.quaternion();
        if t.iter().chain(q.coords.iter()).any(|x| !x.is_finite()) {
            return Err(SimError::NonFiniteBase(format!("{base:?}")));
        }
        self.data.reset();
        let a = self.layout.free_qpos_adr;
        {
            let qpos = self.data.qpos_mut();
            qpos[a..a + 7].copy_from_slice(&[t.x, t.y, t.z, q.w, q.i, q.j, q.k]);
            for (&adr, &v) in self.layout.qpos_adr.iter().zip(joints_rad) {
                qpos[adr] = v;
            }
        }
        self.steps = 0;
        self.fall = None;
        self.torque_on = true;
        self.bad_qacc_warnings = 0;
        self.targets_rad.copy_from_slice(joints_rad);
        self.write_ctrl();
        self.data.forward();
        self.reference_base_z_m = t.z;
        Ok(())
    }

    /// [`Self::reset`] with the base level at the world origin in x, y, facing +x, as low as
    /// the soles allow: the lowest sole corner on the floor.
    pub fn stand(&mut self, joints_rad: &[f64]) -> Result<(), SimError> {
        self.reset(&Isometry3::identity(), joints_rad)?;
        let lowest = self
            .sole_corners_world()
            .iter()
            .flatten()
            .fold(f64::INFINITY, |m, c| m.min(c.z));
        let base = Isometry3::translation(0.0, 0.0, -lowest);
        self.reset(&base, joints_rad)
    }

    /// Sets the servo targets (rad, one per joint). Refuses NaN or infinite values, naming the
    /// joint; nothing changes then.
    pub fn set_targets(&mut self, targets_rad: &[f64]) -> Result<(), SimError> {
        finite_joints(&self.layout.dof_names, "target", targets_rad)?;
        self.targets_rad.copy_from_slice(targets_rad);
        self.write_ctrl();
        Ok(())
    }

    /// The servo targets (rad).
    pub fn targets_rad(&self) -> &[f64] {
        &self.targets_rad
    }

    /// Servo torque on (hold the targets) or off (limp: no spring, only the servo's damping,
    /// as a powered-down geared servo).
    pub fn set_torque(&mut self, on: bool) {
        self.torque_on = on;
        self.write_ctrl();
    }

    /// True while the servos hold their targets.
    pub fn torque_on(&self) -> bool {
        self.torque_on
    }

    fn write_ctrl(&mut self) {
        let (qadr, act) = (&self.layout.qpos_adr, &self.layout.actuator);
        if self.torque_on {
            let ctrl = self.data.ctrl_mut();
            for (&a, &t) in act.iter().zip(&self.targets_rad) {
                ctrl[a] = t;
            }
        } else {
            // Target = where the joint is: the spring term vanishes, the damping stays.
            let q: Vec<f64> = qadr.iter().map(|&i| self.data.qpos()[i]).collect();
            let ctrl = self.data.ctrl_mut();
            for (&a, &v) in act.iter().zip(&q) {
                ctrl[a] = v;
            }
        }
    }

    /// Advances the physics by `duration_s` (rounded to whole steps).
    pub fn step(&mut self, duration_s: f64) -> Result<(), SimError> {
        if !(duration_s.is_finite() && duration_s >= 0.0) {
            return Err(SimError::Time {
                t_s: self.time_s() + duration_s,
                now_s: self.time_s(),
            });
        }
        let n = (duration_s / self.cfg.timestep_s).round() as u64;
        self.physics_steps(n)
    }

    /// Advances the physics to time `t_s`: the steps whose end is at or before `t_s` (within
    /// a millionth of a step). Refuses a time before the current one by more than half a step.
    pub fn advance_to(&mut self, t_s: f64) -> Result<(), SimError> {
        let dt = self.cfg.timestep_s;
        if !t_s.is_finite() || t_s < self.time_s() - 0.5 * dt {
            return Err(SimError::Time {
                t_s,
                now_s: self.time_s(),
            });
        }
        let target = (t_s / dt + 1e-6).floor().max(0.0) as u64;
        self.physics_steps(target.saturating_sub(self.steps))
    }

    /// Advances exactly `n` physics steps, checking for divergence and falls after each.
    pub fn physics_steps(&mut self, n: u64) -> Result<(), SimError> {
        for _ in 0..n {
            if !self.torque_on {
                self.write_ctrl();
            }
            self.data.step();
            self.steps += 1;
            self.check_health()?;
            if self.fall.is_none()
                && let Some(reason) = self.check_fall()
            {
                self.fall = Some(Fall {
                    t_s: self.time_s(),
                    reason,
                });
            }
        }
        Ok(())
    }

    fn check_health(&mut self) -> Result<(), SimError> {
        let warned = self.data.ffi().warning[MjtWarning::mjWARN_BADQACC as usize].number;
        if warned > self.bad_qacc_warnings {
            self.bad_qacc_warnings = warned;
            return Err(SimError::Diverged {
                t_s: self.time_s(),
                why: "MuJoCo found a non-finite acceleration (and reset its state)".into(),
            });
        }
        if let Some(i) = self.data.qpos().iter().position(|x| !x.is_finite()) {
            return Err(SimError::Diverged {
                t_s: self.time_s(),
                why: format!("qpos[{i}] is not finite"),
            });
        }
        Ok(())
    }

    fn check_fall(&self) -> Option<FallReason> {
        let tilt_deg = self.base_tilt_rad().to_degrees();
        if tilt_deg > self.cfg.fall_tilt_deg {
            return Some(FallReason::Tilt { tilt_deg });
        }
        let drop_m = self.reference_base_z_m - self.base_pose().translation.z;
        if drop_m > self.cfg.fall_height_drop_m {
            return Some(FallReason::Dropped { drop_m });
        }
        let c = self.contacts();
        if c.other_force_n > BODY_CONTACT_FRACTION * self.weight_n {
            return Some(FallReason::BodyContact {
                body: c.other_body.unwrap_or_default(),
                force_n: c.other_force_n,
            });
        }
        None
    }

    /// The first fall since the last reset, if any (checked after every physics step).
    pub fn fallen(&self) -> Option<&Fall> {
        self.fall.as_ref()
    }

    /// Joint positions (rad), one per joint.
    pub fn joint_positions_rad(&self) -> Vec<f64> {
        let q = self.data.qpos();
        self.layout.qpos_adr.iter().map(|&i| q[i]).collect()
    }

    /// Joint velocities (rad/s), one per joint.
    pub fn joint_velocities_rad_s(&self) -> Vec<f64> {
        let v = self.data.qvel();
        self.layout.dof_adr.iter().map(|&i| v[i]).collect()
    }

    /// Pose of the base (root link) in the world.
    pub fn base_pose(&self) -> Isometry3<f64> {
        let a = self.layout.free_qpos_adr;
        let q = &self.data.qpos()[a..a + 7];
        Isometry3::from_parts(
            Translation3::new(q[0], q[1], q[2]),
            UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[4], q[5], q[6])),
        )
    }

    /// What an inertial measurement unit fixed at the base link's origin, aligned with the
    /// base, reads: its orientation in the world, the base's angular velocity and the
    /// specific force (acceleration less gravity, what an accelerometer measures), both in
    /// the base's frame. Exact (no noise, no bias): the simulator's ground truth, with the
    /// acceleration of the last physics step.
    pub fn imu(&self) -> ImuReading {
        let orientation = self.base_pose().rotation;
        let v = &self.data.qvel()[self.layout.free_dof_adr..self.layout.free_dof_adr + 6];
        let a = &self.data.qacc()[self.layout.free_dof_adr..self.layout.free_dof_adr + 3];
        let accel_world = Vector3::new(a[0], a[1], a[2]);
        let gravity = Vector3::from(self.data.model().opt().gravity);
        ImuReading {
            orientation,
            angular_velocity_rad_s: Vector3::new(v[3], v[4], v[5]),
            specific_force_m_s2: orientation.inverse_transform_vector(&(accel_world - gravity)),
        }
    }

    /// Angle between the base's z axis and the world's (rad).
    pub fn base_tilt_rad(&self) -> f64 {
        tilt_rad(&self.base_pose())
    }

    /// Whole-body centre of mass (world, m).
    pub fn com_world_m(&self) -> Point3<f64> {
        Point3::from(self.data.subtree_com()[self.layout.base_body])
    }

    /// World position of each foot link's origin, `[left, right]` (m).
    pub fn foot_positions_m(&self) -> [Point3<f64>; 2] {
        self.layout
            .foot_bodies
            .map(|b| Point3::from(self.data.xpos()[b]))
    }

    /// The eight corners of each sole box in the world, `[left, right]` (m).
    pub fn sole_corners_world(&self) -> [[Point3<f64>; 8]; 2] {
        let m = self.data.model();
        self.layout.sole_geoms.map(|g| {
            let p = Vector3::from(self.data.geom_xpos()[g]);
            let r = self.data.geom_xmat()[g];
            let s = m.geom_size()[g];
            let mut out = [Point3::origin(); 8];
            for (k, c) in out.iter_mut().enumerate() {
                let l = [
                    if k & 1 == 0 { s[0] } else { -s[0] },
                    if k & 2 == 0 { s[1] } else { -s[1] },
                    if k & 4 == 0 { s[2] } else { -s[2] },
                ];
                // geom_xmat is row-major.
                *c = Point3::new(
                    p.x + r[0] * l[0] + r[1] * l[1] + r[2] * l[2],
                    p.y + r[3] * l[0] + r[4] * l[1] + r[5] * l[2],
                    p.z + r[6] * l[0] + r[7] * l[1] + r[8] * l[2],
                );
            }
            out
        })
    }

    /// Floor contact forces, centre of pressure and support polygon.
    pub fn contacts(&self) -> ContactReading {
        let d = &self.data;
        let l = &self.layout;
        let geom_body = d.model().geom_bodyid();
        let mut sole_force_n = [0.0; 2];
        let (mut other_force_n, mut other_max) = (0.0, (0.0, None));
        let (mut sum, mut moment) = (0.0, [0.0; 2]);
        for (i, con) in d.contact().iter().enumerate() {
            let g = [con.geom[0] as usize, con.geom[1] as usize];
            let other = match g {
                [a, b] if a == l.floor_geom => b,
                [a, b] if b == l.floor_geom => a,
                _ => continue, // sole on sole: not a floor reaction
            };
            let f = d.try_contact_force(i).map_or(0.0, |w| w[0]);
            let body = geom_body[other] as usize;
            if body == l.foot_bodies[0] {
                sole_force_n[0] += f;
            } else if body == l.foot_bodies[1] {
                sole_force_n[1] += f;
            } else {
                other_force_n += f;
                if f > other_max.0 {
                    other_max = (f, Some(body));
                }
            }
            sum += f;
            moment[0] += f * con.pos[0];
            moment[1] += f * con.pos[1];
        }
        let loaded = sole_force_n.map(|f| f > LOADED_FRACTION * self.weight_n);
        let corners = self.sole_corners_world();
        let mut pts = Vec::with_capacity(16);
        for side in Side::BOTH {
            if loaded[side.index()] {
                pts.extend(corners[side.index()].iter().map(|c| [c.x, c.y]));
            }
        }
        ContactReading {
            normal_force_sum_n: sum,
            sole_force_n,
            other_force_n,
            other_body: other_max.1.map(|b| {
                d.model()
                    .id_to_name(MjtObjBase::mjOBJ_BODY, b)
                    .unwrap_or("?")
                    .to_owned()
            }),
            cop_world_m: (sum >= COP_MIN_FRACTION * self.weight_n)
                .then(|| [moment[0] / sum, moment[1] / sum]),
            loaded,
            support_polygon: convex_hull(&pts),
        }
    }

    /// Static joint torques of a planned pose computed by MuJoCo (N·m, one per joint): the
    /// gravity forces of the model (`qfrc_bias` at rest) minus the floor reactions of
    /// [`crate::static_foot_loads`] mapped through the foot Jacobians. The same quantity as
    /// [`crate::static_torques_nm`] from the URDF mass model; kept as its cross-check.
    pub fn static_torques_nm_mujoco(&self, pose: &StaticPose) -> Result<Vec<f64>, SimError> {
        let l = &self.layout;
        let mut scratch =
            MjData::try_new(self.data.model_clone()).map_err(|e| SimError::Mujoco {
                stage: "allocate data for",
                message: e.to_string(),
            })?;
        finite_joints(&l.dof_names, "position", pose.joints_rad)?;
        let t = pose.base_world.translation.vector;
        let q = pose.base_world.rotation.quaternion();
        {
            let a = l.free_qpos_adr;
            let qpos = scratch.qpos_mut();
            qpos[a..a + 7].copy_from_slice(&[t.x, t.y, t.z, q.w, q.i, q.j, q.k]);
            for (&adr, &v) in l.qpos_adr.iter().zip(pose.joints_rad) {
                qpos[adr] = v;
            }
        }
        scratch.forward();
        let nv = scratch.model().ffi().nv as usize;
        let mut tau = scratch.qfrc_bias().to_vec();
        for load in static_foot_loads(&self.biped, pose, self.weight_n)? {
            let body = l.foot_bodies[load.side.index()];
            let p = load.point_world_m;
            let (jacp, _) = scratch
                .try_jac(true, false, &[p.x, p.y, p.z], body)
                .map_err(|e| SimError::Mujoco {
                    stage: "take a Jacobian of",
                    message: e.to_string(),
                })?;
            for (v, t) in tau.iter_mut().enumerate().take(nv) {
                *t -= jacp[2 * nv + v] * load.force_n;
            }
        }
        Ok(l.dof_adr.iter().map(|&i| tau[i]).collect())
    }
}
