//! Servo-sag compensation of planned poses: ik_solver's statics
//! ([`ik_solver::BipedModel::static_torques_nm`]) with the floor reactions where the plan
//! puts the support and the CoM. ALGORITHM.md, "Position servos are springs".
//!
//! Pure functions of the URDF mass model and a [`GaitSample`]: no physics engine. The fleet
//! (the joint bridge) compensates from the commanded joint vector alone with
//! [`ik_solver::BipedModel::sag_compensation_rad`]; these take the plan's own support and
//! CoM, for the physics tests and the plan player.

use gait_planner::{GaitSample, Support};
use ik_solver::{BipedModel, FootLoad, GRAVITY_M_S2, IkError, Side, Stance};
use nalgebra::Isometry3;

use crate::error::SimError;

fn ik_error(e: IkError) -> SimError {
    match e {
        IkError::JointCount { expected, got } => SimError::JointCount {
            what: "plan sample",
            expected,
            got,
        },
        IkError::NonFiniteJoint { joint, value } => SimError::NonFinite {
            joint,
            what: "planned position",
            value,
        },
        other => SimError::Plan(other.to_string()),
    }
}

fn stance(sample: &GaitSample) -> Stance {
    match sample.support {
        Support::Left => Stance::Single(Side::Left),
        Support::Right => Stance::Single(Side::Right),
        Support::Double => Stance::Double,
    }
}

fn poses(model: &BipedModel, sample: &GaitSample) -> Result<Vec<Isometry3<f64>>, SimError> {
    model
        .robot()
        .link_poses(&sample.base_world, &sample.joints_rad)
        .map_err(ik_error)
}

/// The floor reactions that hold the planned pose still with the centre of pressure under
/// the planned CoM, for a robot of weight `weight_n`.
pub fn static_foot_loads(
    model: &BipedModel,
    sample: &GaitSample,
    weight_n: f64,
) -> Result<Vec<FootLoad>, SimError> {
    let c = sample.com_world_m;
    if !c.coords.iter().all(|x| x.is_finite()) {
        return Err(SimError::Plan(format!(
            "t = {} s: CoM {c} is not finite",
            sample.t_s
        )));
    }
    let poses = poses(model, sample)?;
    Ok(model.static_foot_loads(&poses, c, stance(sample), weight_n))
}

/// The static torque (N·m; N for a prismatic joint) each joint's servo must give to hold
/// the planned pose of `sample` with the floor reactions of [`static_foot_loads`], one per
/// joint in [`ik_solver::RobotModel::dof_names`] order. Positive along the joint axis.
///
/// ```
/// use ik_solver::{BipedModel, DEFAULT_URDF};
/// let model = BipedModel::from_urdf_str(DEFAULT_URDF, None).unwrap();
/// let plan = gait_planner::plan_walk(model.clone(), Default::default(), 1).unwrap();
/// // Standing on the right foot, the left one in the air.
/// let s = plan.iter().find(|s| s.support == gait_planner::Support::Right).unwrap();
/// let tau = sim_bridge::static_torques_nm(&model, s).unwrap();
/// let (r, l) = (model.robot().dof_index("r_knee").unwrap(), model.robot().dof_index("l_knee").unwrap());
/// // The bent stance knee carries the robot; the swing knee only its shin and foot.
/// assert!(tau[r].abs() > 0.2 && tau[l].abs() < 0.1, "{} {}", tau[r], tau[l]);
/// ```
pub fn static_torques_nm(model: &BipedModel, sample: &GaitSample) -> Result<Vec<f64>, SimError> {
    let weight_n = model.robot().total_mass_kg() * GRAVITY_M_S2;
    let loads = static_foot_loads(model, sample, weight_n)?;
    Ok(model.static_torques_nm(&poses(model, sample)?, &loads))
}

/// The sag compensation of [`static_torques_nm`]: torque / kp per joint (rad), to add to the
/// planned joint positions.
pub fn static_compensation_rad(
    model: &BipedModel,
    sample: &GaitSample,
    kp_nm_per_rad: f64,
) -> Result<Vec<f64>, SimError> {
    if !(kp_nm_per_rad.is_finite() && kp_nm_per_rad > 0.0) {
        return Err(SimError::Config {
            key: "kp_nm_per_rad",
            value: kp_nm_per_rad,
            why: "must be above 0 N·m/rad".into(),
        });
    }
    Ok(static_torques_nm(model, sample)?
        .into_iter()
        .map(|t| t / kp_nm_per_rad)
        .collect())
}

/// Servo targets for a planned pose: the planned joint positions plus
/// [`static_compensation_rad`].
pub fn compensated_targets_rad(
    model: &BipedModel,
    sample: &GaitSample,
    kp_nm_per_rad: f64,
) -> Result<Vec<f64>, SimError> {
    let offsets = static_compensation_rad(model, sample, kp_nm_per_rad)?;
    Ok(sample
        .joints_rad
        .iter()
        .zip(offsets)
        .map(|(q, o)| q + o)
        .collect())
}
