//! The MuJoCo model of a biped, built from its URDF with MuJoCo's model editor (MjSpec).
//!
//! What the URDF import gets added, and why:
//! - a free joint on the root link: the robot stands and falls on its own;
//! - a floor plane; collisions only where a walk needs them: soles with the floor (and with
//!   each other, so feet cannot pass through each other), the rest of the body with the floor
//!   only (that contact is how a fall shows), never body against body;
//! - one position servo per movable joint, in [`ik_solver::RobotModel::dof_names`] order:
//!   torque = kp·(target − q) − kv·q̇, clipped to the joint's torque limit, plus the
//!   servo's rotor inertia (armature);
//! - a 1 ms (configurable) step with the implicit-in-velocity integrator, which keeps the
//!   servo damping stable.
//!
//! Static links (a torso fixed to the pelvis) are fused into their parent body, visual
//! geometry is dropped; inertials are the URDF's.

use std::sync::Arc;

use ik_solver::{BipedModel, JointKind, Side};
use mujoco_rs::prelude::*;
use mujoco_rs::wrappers::mj_editing::{MjtLimited, PositionConfig};

use crate::config::SimConfig;
use crate::error::SimError;

/// Collision bits: soles collide with the floor and each other; the rest of the body with
/// the floor only.
const SOLE_CONTYPE: i32 = 1;
const SOLE_CONAFFINITY: i32 = 1;
const BODY_CONTYPE: i32 = 0;
const BODY_CONAFFINITY: i32 = 2;
const FLOOR_CONTYPE: i32 = 3;
const FLOOR_CONAFFINITY: i32 = 1;
/// Name of the added free joint and floor.
const ROOT_JOINT: &str = "sim_bridge_root";
const FLOOR: &str = "sim_bridge_floor";

/// Where things are in the compiled model.
#[derive(Debug, Clone)]
pub(crate) struct Layout {
    /// Movable joints, in RobotModel dof order.
    pub dof_names: Vec<String>,
    /// qpos address of each dof.
    pub qpos_adr: Vec<usize>,
    /// qvel address of each dof.
    pub dof_adr: Vec<usize>,
    /// Actuator (= ctrl index) of each dof.
    pub actuator: Vec<usize>,
    /// qpos address of the free joint (position, then quaternion w x y z).
    pub free_qpos_adr: usize,
    /// qvel address of the free joint (linear velocity in the world, then angular velocity
    /// in the base's own frame).
    pub free_dof_adr: usize,
    /// The root link's body.
    pub base_body: usize,
    /// The foot bodies, `[left, right]`.
    pub foot_bodies: [usize; 2],
    /// The sole box of each foot: its lowest box geom.
    pub sole_geoms: [usize; 2],
    /// The floor plane.
    pub floor_geom: usize,
    /// Warnings MuJoCo gave while compiling.
    pub warnings: Vec<String>,
}

fn mujoco_err(stage: &'static str) -> impl Fn(MjEditError) -> SimError {
    move |e| SimError::Mujoco {
        stage,
        message: e.to_string(),
    }
}

pub(crate) fn find(
    model: &MjModel,
    obj: MjtObjBase,
    kind: &'static str,
    name: &str,
) -> Result<usize, SimError> {
    model
        .name_to_id(obj, name)
        .ok_or_else(|| SimError::Missing {
            kind,
            name: name.to_owned(),
        })
}

/// Compiles the MuJoCo model of `biped`, whose URDF text is `urdf`.
pub(crate) fn build(
    urdf: &str,
    biped: &BipedModel,
    cfg: &SimConfig,
) -> Result<(Arc<MjModel>, Layout), SimError> {
    let robot = biped.robot();
    // MuJoCo takes a C string: a NUL byte would end the text early (and mujoco-rs panics).
    if urdf.contains('\0') {
        return Err(SimError::Mujoco {
            stage: "parse",
            message: "the URDF text contains a NUL byte".into(),
        });
    }
    // Torque limit of every dof, refused before anything is built.
    let mut torque_limits_nm = Vec::with_capacity(robot.dof_count());
    for &j in robot.dof_joints() {
        let joint = &robot.joints()[j];
        let limit = match cfg.torque_limit_nm {
            Some(t) => t,
            None => {
                let effort = joint.limits.map_or(0.0, |l| l.effort);
                if !(effort.is_finite() && effort > 0.0) {
                    return Err(SimError::TorqueLimit {
                        joint: joint.name.clone(),
                        effort_nm: effort,
                    });
                }
                effort
            }
        };
        torque_limits_nm.push(limit);
    }

    let mut spec = MjSpec::from_xml_string(urdf).map_err(mujoco_err("parse"))?;
    spec.compiler_mut().set_fusestatic(true);
    spec.compiler_mut().set_discardvisual(true);
    {
        let o = spec.option_mut();
        o.timestep = cfg.timestep_s;
        o.integrator = MjtIntegrator::mjINT_IMPLICITFAST as i32;
        o.cone = MjtCone::mjCONE_PYRAMIDAL as i32;
    }

    for g in spec.geom_iter_mut() {
        g.set_contype(BODY_CONTYPE);
        g.set_conaffinity(BODY_CONAFFINITY);
        g.friction_mut()[0] = cfg.friction;
    }
    for side in Side::BOTH {
        let foot = &robot.links()[biped.leg(side).foot_link].name;
        let body = spec.body_mut(foot).ok_or_else(|| SimError::Missing {
            kind: "body",
            name: foot.clone(),
        })?;
        for g in body.geom_iter_mut(false) {
            g.set_contype(SOLE_CONTYPE);
            g.set_conaffinity(SOLE_CONAFFINITY);
        }
    }
    for j in spec.joint_iter_mut() {
        j.set_armature(cfg.armature_kg_m2);
    }

    let root = &robot.links()[robot.root()].name;
    spec.body_mut(root)
        .ok_or_else(|| SimError::Missing {
            kind: "body",
            name: root.clone(),
        })?
        .add_free_joint()
        .set_name(ROOT_JOINT)
        .map_err(mujoco_err("name the free joint of"))?;

    let floor = spec
        .world_body_mut()
        .add_geom()
        .with_type(MjtGeomBase::mjGEOM_PLANE)
        .with_size([5.0, 5.0, 0.1]);
    floor
        .set_name(FLOOR)
        .map_err(mujoco_err("name the floor of"))?;
    floor.set_contype(FLOOR_CONTYPE);
    floor.set_conaffinity(FLOOR_CONAFFINITY);
    floor.friction_mut()[0] = cfg.friction;

    let dof_names: Vec<String> = robot.dof_names().map(str::to_owned).collect();
    for (name, &limit) in dof_names.iter().zip(&torque_limits_nm) {
        let a = spec.add_actuator().with_trntype(MjtTrn::mjTRN_JOINT);
        a.set_target(name);
        a.set_name(&format!("{name}_servo"))
            .map_err(mujoco_err("name a servo of"))?;
        a.set_to_position(
            PositionConfig::default()
                .with_kp(cfg.kp_nm_per_rad)
                .with_kv(cfg.kv_nm_s_per_rad),
        )
        .map_err(mujoco_err("make a position servo in"))?;
        a.forcerange_mut().copy_from_slice(&[-limit, limit]);
        a.set_forcelimited(MjtLimited::mjLIMITED_TRUE);
    }

    let model = spec.compile().map_err(mujoco_err("compile"))?;
    let warnings = (0..spec.num_warnings())
        .filter_map(|i| spec.warning(i).map(str::to_owned))
        .collect();

    let mut qpos_adr = Vec::with_capacity(dof_names.len());
    let mut dof_adr = Vec::with_capacity(dof_names.len());
    let mut actuator = Vec::with_capacity(dof_names.len());
    for (name, &j) in dof_names.iter().zip(robot.dof_joints()) {
        let mj = find(&model, MjtObjBase::mjOBJ_JOINT, "joint", name)?;
        let expected = match robot.joints()[j].kind {
            JointKind::Prismatic => MjtJoint::mjJNT_SLIDE,
            _ => MjtJoint::mjJNT_HINGE,
        };
        if model.jnt_type()[mj] != expected {
            return Err(SimError::Missing {
                kind: "joint of the URDF's type",
                name: name.clone(),
            });
        }
        qpos_adr.push(model.jnt_qposadr()[mj] as usize);
        dof_adr.push(model.jnt_dofadr()[mj] as usize);
        actuator.push(find(
            &model,
            MjtObjBase::mjOBJ_ACTUATOR,
            "actuator",
            &format!("{name}_servo"),
        )?);
    }
    let free = find(&model, MjtObjBase::mjOBJ_JOINT, "joint", ROOT_JOINT)?;
    let base_body = find(&model, MjtObjBase::mjOBJ_BODY, "body", root)?;
    let foot_bodies = Side::BOTH.map(|s| &robot.links()[biped.leg(s).foot_link].name);
    let foot_bodies = [
        find(&model, MjtObjBase::mjOBJ_BODY, "body", foot_bodies[0])?,
        find(&model, MjtObjBase::mjOBJ_BODY, "body", foot_bodies[1])?,
    ];
    let sole_geoms = [
        sole_geom(&model, foot_bodies[0], biped, Side::Left)?,
        sole_geom(&model, foot_bodies[1], biped, Side::Right)?,
    ];
    let layout = Layout {
        dof_names,
        qpos_adr,
        dof_adr,
        actuator,
        free_qpos_adr: model.jnt_qposadr()[free] as usize,
        free_dof_adr: model.jnt_dofadr()[free] as usize,
        base_body,
        foot_bodies,
        sole_geoms,
        floor_geom: find(&model, MjtObjBase::mjOBJ_GEOM, "geom", FLOOR)?,
        warnings,
    };
    Ok((Arc::new(model), layout))
}

/// The foot's sole: of the foot body's box geoms, the one whose lowest point (in the body
/// frame, along the base's vertical at zero angles) is lowest.
pub(crate) fn sole_geom(
    model: &MjModel,
    body: usize,
    biped: &BipedModel,
    side: Side,
) -> Result<usize, SimError> {
    // Down in the foot frame at zero angles.
    let down = biped.leg(side).foot_rotation0.inverse() * nalgebra::Vector3::new(0.0, 0.0, -1.0);
    let mut best: Option<(usize, f64)> = None;
    for (g, (&b, &t)) in model
        .geom_bodyid()
        .iter()
        .zip(model.geom_type())
        .enumerate()
    {
        if b as usize != body || t != MjtGeomBase::mjGEOM_BOX {
            continue;
        }
        let pos = model.geom_pos()[g];
        let q = model.geom_quat()[g];
        let rot = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            q[0], q[1], q[2], q[3],
        ));
        let half = model.geom_size()[g];
        // Farthest reach of the box along `down`.
        let local_down = rot.inverse() * down;
        let reach = nalgebra::Vector3::from(pos).dot(&down)
            + (0..3).map(|k| half[k] * local_down[k].abs()).sum::<f64>();
        if best.is_none_or(|(_, r)| reach > r) {
            best = Some((g, reach));
        }
    }
    best.map(|(g, _)| g).ok_or_else(|| SimError::Missing {
        kind: "box collision geom (the sole) on body",
        name: model
            .id_to_name(MjtObjBase::mjOBJ_BODY, body)
            .unwrap_or("?")
            .to_owned(),
    })
}
