//! Position servos are springs (ALGORITHM.md): under the robot's weight each joint sags
//! below its target by about torque / kp. The mass model gives the static torque of every
//! planned pose, so aiming each servo torque / kp beyond the plan cancels most of the sag.
//!
//! Pure functions of the URDF mass model and a [`GaitSample`]: no physics engine, so a real
//! robot's pipeline can use them too.
//!
//! The floor carries the weight where the plan puts the CoM: in single support all of it on
//! the stance sole, under the CoM; in double support split between the soles by where the
//! CoM lies along the line joining their centres, each share under the CoM's offset from
//! that line (so the centre of pressure is under the CoM and the base needs no force).

use gait_planner::{GaitSample, Support};
use ik_solver::{BipedModel, IkError, JointKind, Side};
use nalgebra::{Point3, Vector3};

use crate::error::SimError;

/// Standard gravity (m/s²), MuJoCo's default.
pub const GRAVITY_M_S2: f64 = 9.81;

/// A vertical floor reaction on one sole.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FootLoad {
    /// Which sole.
    pub side: Side,
    /// Upward force (N).
    pub force_n: f64,
    /// Where it acts: a point on the sole plane (world, m).
    pub point_world_m: Point3<f64>,
}

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
    let sole_centre = |s: Side| {
        let a = sample.ankles_world_m[s.index()];
        let leg = model.leg(s);
        let r = &leg.sole;
        Point3::new(
            a.x + (r.x_min_m + r.x_max_m) / 2.0,
            a.y + (r.y_min_m + r.y_max_m) / 2.0,
            a.z - leg.ankle_to_sole_m,
        )
    };
    let under_com = |s: Side, offset: Vector3<f64>| {
        let p = sole_centre(s) + offset;
        FootLoad {
            side: s,
            force_n: 0.0,
            point_world_m: Point3::new(p.x, p.y, sole_centre(s).z),
        }
    };
    Ok(match sample.support {
        Support::Left | Support::Right => {
            let s = if sample.support == Support::Left {
                Side::Left
            } else {
                Side::Right
            };
            let z = sole_centre(s).z;
            vec![FootLoad {
                side: s,
                force_n: weight_n,
                point_world_m: Point3::new(c.x, c.y, z),
            }]
        }
        Support::Double => {
            let (l, r) = (sole_centre(Side::Left), sole_centre(Side::Right));
            let e = Vector3::new(l.x - r.x, l.y - r.y, 0.0);
            let to_c = Vector3::new(c.x - r.x, c.y - r.y, 0.0);
            let share_left = if e.norm_squared() > 0.0 {
                (to_c.dot(&e) / e.norm_squared()).clamp(0.0, 1.0)
            } else {
                0.5
            };
            let on_line = Vector3::new(r.x, r.y, 0.0) + e * share_left;
            let offset = Vector3::new(c.x - on_line.x, c.y - on_line.y, 0.0);
            let mut left = under_com(Side::Left, offset);
            left.force_n = share_left * weight_n;
            let mut right = under_com(Side::Right, offset);
            right.force_n = (1.0 - share_left) * weight_n;
            vec![left, right]
        }
    })
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
    let robot = model.robot();
    let poses = robot
        .link_poses(&sample.base_world, &sample.joints_rad)
        .map_err(ik_error)?;
    let weight_n = robot.total_mass_kg() * GRAVITY_M_S2;
    let loads = static_foot_loads(model, sample, weight_n)?;
    // Is `link` below joint `joint` (moved by it)?
    let below = |joint: usize, mut link: usize| {
        while let Some(j) = robot.links()[link].parent_joint {
            if j == joint {
                return true;
            }
            link = robot.joints()[j].parent;
        }
        false
    };
    let mut tau = Vec::with_capacity(robot.dof_count());
    for &ji in robot.dof_joints() {
        let joint = &robot.joints()[ji];
        let frame = robot.joint_frame(&poses, ji);
        let axis = frame.rotation * joint.axis.into_inner();
        let p = Point3::from(frame.translation.vector);
        let (mass_kg, com) = robot.subtree_mass_and_com(&poses, ji);
        let gravity = Vector3::new(0.0, 0.0, -mass_kg * GRAVITY_M_S2);
        let mut force = gravity;
        let mut moment = (com - p).cross(&gravity);
        for load in &loads {
            if below(ji, model.leg(load.side).foot_link) {
                let f = Vector3::new(0.0, 0.0, load.force_n);
                force += f;
                moment += (load.point_world_m - p).cross(&f);
            }
        }
        // The servo balances what gravity and the floor do to everything below the joint.
        tau.push(match joint.kind {
            JointKind::Prismatic => -axis.dot(&force),
            _ => -axis.dot(&moment),
        });
    }
    Ok(tau)
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
