//! Servo-sag compensation of planned poses: ik_solver's statics
//! ([`ik_solver::BipedModel::static_torques_nm`]) with the floor reactions where the plan
//! puts the support and the CoM. ALGORITHM.md, "Position servos are springs".
//!
//! Pure functions of the URDF mass model and a [`StaticPose`] (a planned pose: base, joints,
//! CoM and the soles that carry it): no physics engine. The fleet (the joint bridge)
//! compensates from the commanded joint vector alone with
//! [`ik_solver::BipedModel::sag_compensation_rad`]; these take the plan's own support and
//! CoM, for the physics tests and the plan player (walk_eval).

use ik_solver::{BipedModel, FootLoad, GRAVITY_M_S2, IkError, StaticPose};
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

fn poses(model: &BipedModel, pose: &StaticPose) -> Result<Vec<Isometry3<f64>>, SimError> {
    model
        .robot()
        .link_poses(pose.base_world, pose.joints_rad)
        .map_err(ik_error)
}

/// The floor reactions that hold the planned pose still with the centre of pressure under
/// the planned CoM, for a robot of weight `weight_n`.
///
/// ```
/// use ik_solver::{BipedModel, DEFAULT_URDF, Side, Stance, StaticPose};
/// use nalgebra::{Isometry3, Point3};
/// let model = BipedModel::from_urdf_str(DEFAULT_URDF, None).unwrap();
/// let (base, joints) = (Isometry3::identity(), vec![0.0; model.robot().dof_count()]);
/// let poses = model.robot().link_poses(&base, &joints).unwrap();
/// let (l, r) = (model.sole_centre_world(&poses, Side::Left), model.sole_centre_world(&poses, Side::Right));
/// // On both soles with the CoM midway between their centres: each carries half of 10 N.
/// let pose = StaticPose {
///     base_world: &base,
///     joints_rad: &joints,
///     com_world_m: Point3::new((l.x + r.x) / 2.0, (l.y + r.y) / 2.0, 0.3),
///     stance: Stance::Double,
/// };
/// let loads = sim_bridge::static_foot_loads(&model, &pose, 10.0).unwrap();
/// assert_eq!(loads.len(), 2);
/// assert!(loads.iter().all(|f| (f.force_n - 5.0).abs() < 1e-9), "{loads:?}");
/// // Standing on the right sole alone, it carries all of it, under the CoM.
/// let pose = StaticPose { stance: Stance::Single(Side::Right), ..pose };
/// let loads = sim_bridge::static_foot_loads(&model, &pose, 10.0).unwrap();
/// assert_eq!((loads.len(), loads[0].side, loads[0].force_n), (1, Side::Right, 10.0));
/// ```
pub fn static_foot_loads(
    model: &BipedModel,
    pose: &StaticPose,
    weight_n: f64,
) -> Result<Vec<FootLoad>, SimError> {
    loads_of(model, pose, &poses(model, pose)?, weight_n)
}

/// [`static_foot_loads`] with the pose's link poses already computed.
fn loads_of(
    model: &BipedModel,
    pose: &StaticPose,
    link_poses: &[Isometry3<f64>],
    weight_n: f64,
) -> Result<Vec<FootLoad>, SimError> {
    let c = pose.com_world_m;
    if !c.coords.iter().all(|x| x.is_finite()) {
        return Err(SimError::Plan(format!("the planned CoM {c} is not finite")));
    }
    Ok(model.static_foot_loads(link_poses, c, pose.stance, weight_n))
}

/// The static torque (N·m; N for a prismatic joint) each joint's servo must give to hold
/// the planned pose with the floor reactions of [`static_foot_loads`], one per joint in
/// [`ik_solver::RobotModel::dof_names`] order. Positive along the joint axis.
pub fn static_torques_nm(model: &BipedModel, pose: &StaticPose) -> Result<Vec<f64>, SimError> {
    let weight_n = model.robot().total_mass_kg() * GRAVITY_M_S2;
    let link_poses = poses(model, pose)?;
    let loads = loads_of(model, pose, &link_poses, weight_n)?;
    Ok(model.static_torques_nm(&link_poses, &loads))
}

/// The sag compensation of [`static_torques_nm`]: torque / kp per joint (rad), to add to the
/// planned joint positions.
pub fn static_compensation_rad(
    model: &BipedModel,
    pose: &StaticPose,
    kp_nm_per_rad: f64,
) -> Result<Vec<f64>, SimError> {
    if !(kp_nm_per_rad.is_finite() && kp_nm_per_rad > 0.0) {
        return Err(SimError::Config {
            key: "kp_nm_per_rad",
            value: kp_nm_per_rad,
            why: "must be above 0 N·m/rad".into(),
        });
    }
    Ok(static_torques_nm(model, pose)?
        .into_iter()
        .map(|t| t / kp_nm_per_rad)
        .collect())
}

/// Servo targets for a planned pose: the planned joint positions plus
/// [`static_compensation_rad`].
pub fn compensated_targets_rad(
    model: &BipedModel,
    pose: &StaticPose,
    kp_nm_per_rad: f64,
) -> Result<Vec<f64>, SimError> {
    let offsets = static_compensation_rad(model, pose, kp_nm_per_rad)?;
    Ok(pose
        .joints_rad
        .iter()
        .zip(offsets)
        .map(|(q, o)| q + o)
        .collect())
}
