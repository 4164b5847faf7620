//! A robot from a given MJCF scene, tied to its URDF by a joint map.
//!
//! The URDF stays the robot model of the planner and the IK (joint vectors in its
//! [`ik_solver::RobotModel::dof_names`] order); the MJCF scene is what MuJoCo simulates. The
//! [`JointMap`] says which scene joint, actuator, body and geom is which URDF joint or link:
//!
//! ```yaml
//! links:               # URDF link -> scene body: the root link and both foot links
//!   base_link: torso
//!   l_foot: l_foot_body
//!   r_foot: r_foot_body
//! soles:               # optional: URDF foot link -> the scene's sole box geom
//!   l_foot: l_sole     # (default: the foot body's lowest box geom)
//! floor_geom: floor    # optional (default: the only plane geom of the world body)
//! joints:              # every movable URDF joint -> scene joint and its position actuator
//!   l_hip_roll: {joint: l_hip_roll_j, actuator: act_l_hip_roll}
//! ```
//!
//! What the scene owns and what [`crate::SimConfig`] gives:
//! - the scene: bodies, masses, geometry and contacts (which geoms collide, friction), the
//!   floor, joint limits, armature and damping, the servos (each a `<position>` actuator:
//!   its `kp`, `kv`, force range), the timestep, the integrator and gravity. Nothing of the
//!   scene is changed.
//! - the config: what sim_bridge decides around the physics: the fall bounds
//!   (`fall_tilt_deg`, `fall_height_drop_m`) and `settle_s`. Its physics keys
//!   (`kp_nm_per_rad`, `kv_nm_s_per_rad`, `torque_limit_nm`, `armature_kg_m2`,
//!   `timestep_s`, `friction`) are replaced by the scene's values, so [`crate::Sim::config`]
//!   tells what is simulated (the sag compensation uses its `kp_nm_per_rad`).
//!
//! The scene must have exactly one free joint, on the base body; every hinge or slide joint
//! and every actuator of the scene must be in the map (an unmapped one would move or push
//! unseen); every servo must be a plain position servo on its joint (gear 1, no activation
//! dynamics, force = kp·(target − q) − kv·q̇) and all share one `kp`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::sync::Arc;

use ik_solver::{BipedModel, JointKind, Side};
use mujoco_rs::prelude::*;
use serde::{Deserialize, Serialize};

use crate::config::SimConfig;
use crate::error::SimError;
use crate::mjmodel::{Layout, find, sole_geom};

/// The scene joint and actuator of one URDF joint.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MappedJoint {
    /// The scene's hinge or slide joint.
    pub joint: String,
    /// The scene's position actuator driving it.
    pub actuator: String,
}

/// Names of the URDF robot in an MJCF scene (see the module docs for the YAML layout).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointMap {
    /// URDF link → scene body, for the root link and both foot links.
    pub links: BTreeMap<String, String>,
    /// URDF foot link → the scene's sole box geom; a foot left out uses its body's lowest
    /// box geom.
    #[serde(default)]
    pub soles: BTreeMap<String, String>,
    /// The scene's floor geom; `None`: the only plane geom of the world body.
    #[serde(default)]
    pub floor_geom: Option<String>,
    /// Every movable URDF joint → its scene joint and actuator.
    pub joints: BTreeMap<String, MappedJoint>,
}

fn map_err(key: impl Into<String>, why: impl Into<String>) -> SimError {
    SimError::JointMap {
        key: key.into(),
        why: why.into(),
    }
}

impl JointMap {
    /// Parses the YAML text; unknown keys are refused by name. Names are checked against
    /// the robot and the scene when a [`crate::Sim`] is built.
    pub fn from_yaml_str(text: &str) -> Result<Self, SimError> {
        serde_norway::from_str(text).map_err(|e| map_err("(file)", e.to_string()))
    }

    /// Reads and parses a joint map file.
    pub fn from_yaml_file(path: impl AsRef<Path>) -> Result<Self, SimError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path)
            .map_err(|e| map_err("(file)", format!("cannot read {}: {e}", path.display())))?;
        Self::from_yaml_str(&text).map_err(|e| match e {
            SimError::JointMap { key, why } => map_err(key, format!("{}: {why}", path.display())),
            other => other,
        })
    }

    /// Checks the map against the URDF robot: every movable joint mapped once, no unknown
    /// joint or link, the root and foot links given, no scene name used twice.
    fn check_against(&self, biped: &BipedModel) -> Result<(), SimError> {
        let robot = biped.robot();
        let dofs: BTreeSet<&str> = robot.dof_names().collect();
        let forgotten: Vec<&str> = robot
            .dof_names()
            .filter(|n| !self.joints.contains_key(*n))
            .collect();
        if !forgotten.is_empty() {
            return Err(map_err(
                "joints",
                format!(
                    "the URDF's movable joints {} are not mapped",
                    forgotten.join(", ")
                ),
            ));
        }
        if let Some(extra) = self.joints.keys().find(|k| !dofs.contains(k.as_str())) {
            return Err(map_err(
                format!("joints.{extra}"),
                "not a movable joint of the URDF",
            ));
        }
        let mut seen_joint = BTreeMap::new();
        let mut seen_act = BTreeMap::new();
        for (urdf, m) in &self.joints {
            if let Some(other) = seen_joint.insert(m.joint.as_str(), urdf) {
                return Err(map_err(
                    format!("joints.{urdf}.joint"),
                    format!("scene joint `{}` is already mapped to `{other}`", m.joint),
                ));
            }
            if let Some(other) = seen_act.insert(m.actuator.as_str(), urdf) {
                return Err(map_err(
                    format!("joints.{urdf}.actuator"),
                    format!("actuator `{}` is already mapped to `{other}`", m.actuator),
                ));
            }
        }
        let links = robot.links();
        let required: Vec<&str> = std::iter::once(robot.root())
            .chain(Side::BOTH.map(|s| biped.leg(s).foot_link))
            .map(|l| links[l].name.as_str())
            .collect();
        if let Some(missing) = required.iter().find(|l| !self.links.contains_key(**l)) {
            return Err(map_err(
                "links",
                format!(
                    "no scene body for URDF link `{missing}` (the root and foot links are needed)"
                ),
            ));
        }
        if let Some(extra) = self.links.keys().find(|k| !required.contains(&k.as_str())) {
            return Err(map_err(
                format!("links.{extra}"),
                format!(
                    "only the root and foot links are used: {}",
                    required.join(", ")
                ),
            ));
        }
        if let Some(extra) = self
            .soles
            .keys()
            .find(|k| !required[1..].contains(&k.as_str()))
        {
            return Err(map_err(
                format!("soles.{extra}"),
                format!("not a foot link: {}, {}", required[1], required[2]),
            ));
        }
        Ok(())
    }
}

/// Where the scene comes from.
pub(crate) enum Source<'a> {
    Text(&'a str),
    File(&'a Path),
}

fn mujoco_err(stage: &'static str) -> impl Fn(MjEditError) -> SimError {
    move |e| SimError::Mujoco {
        stage,
        message: e.to_string(),
    }
}

fn name_of(model: &MjModel, obj: MjtObjBase, id: usize) -> String {
    model.id_to_name(obj, id).unwrap_or("(unnamed)").to_owned()
}

fn servo_err(actuator: &str, why: impl Into<String>) -> SimError {
    SimError::Servo {
        actuator: actuator.to_owned(),
        why: why.into(),
    }
}

/// Loads and compiles the scene, checks it against `map` and the robot, and returns the
/// model, where things are in it, and `cfg` with the scene's physics values.
pub(crate) fn load(
    source: Source<'_>,
    map: &JointMap,
    biped: &BipedModel,
    cfg: &SimConfig,
) -> Result<(Arc<MjModel>, Layout, SimConfig), SimError> {
    map.check_against(biped)?;
    let mut spec = match source {
        Source::Text(text) => {
            // MuJoCo takes a C string: a NUL byte would end the text early (and mujoco-rs
            // panics).
            if text.contains('\0') {
                return Err(SimError::Mujoco {
                    stage: "parse",
                    message: "the MJCF text contains a NUL byte".into(),
                });
            }
            MjSpec::from_xml_string(text).map_err(mujoco_err("parse"))?
        }
        Source::File(path) => {
            let shown = path.display().to_string();
            if shown.contains('\0') {
                return Err(SimError::Mujoco {
                    stage: "parse",
                    message: format!("the path {shown:?} contains a NUL byte"),
                });
            }
            if !path.is_file() {
                return Err(SimError::Mujoco {
                    stage: "read",
                    message: format!("no MJCF file at {shown}"),
                });
            }
            MjSpec::from_xml(path).map_err(mujoco_err("parse"))?
        }
    };
    let model = spec.compile().map_err(mujoco_err("compile"))?;
    let warnings = (0..spec.num_warnings())
        .filter_map(|i| spec.warning(i).map(str::to_owned))
        .collect();

    let robot = biped.robot();
    let links = robot.links();
    let body = |urdf_link: &str| -> Result<usize, SimError> {
        let scene = map.links.get(urdf_link).ok_or_else(|| {
            map_err(
                "links",
                format!("no scene body for URDF link `{urdf_link}`"),
            )
        })?;
        find(&model, MjtObjBase::mjOBJ_BODY, "body", scene)
    };
    let base_body = body(&links[robot.root()].name)?;
    let foot_names = Side::BOTH.map(|s| links[biped.leg(s).foot_link].name.clone());
    let foot_bodies = [body(&foot_names[0])?, body(&foot_names[1])?];

    // The free joint: exactly one, on the base body.
    let free: Vec<usize> = (0..model.jnt_type().len())
        .filter(|&j| model.jnt_type()[j] == MjtJoint::mjJNT_FREE)
        .collect();
    let free = match free.as_slice() {
        [] => {
            return Err(map_err(
                "(scene)",
                "the scene has no free joint: the robot would be welded to the world",
            ));
        }
        [j] => *j,
        more => {
            return Err(map_err(
                "(scene)",
                format!(
                    "the scene has {} free joints ({}); one robot, one free joint",
                    more.len(),
                    more.iter()
                        .map(|&j| name_of(&model, MjtObjBase::mjOBJ_JOINT, j))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        }
    };
    let free_body = model.jnt_bodyid()[free] as usize;
    if free_body != base_body {
        return Err(map_err(
            format!("links.{}", links[robot.root()].name),
            format!(
                "the scene's free joint is on body `{}`, not on the base body `{}`",
                name_of(&model, MjtObjBase::mjOBJ_BODY, free_body),
                name_of(&model, MjtObjBase::mjOBJ_BODY, base_body)
            ),
        ));
    }

    // Joints and their servos.
    let dof_names: Vec<String> = robot.dof_names().map(str::to_owned).collect();
    let n = dof_names.len();
    let (mut qpos_adr, mut dof_adr, mut actuator) = (
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
    );
    let (mut mapped_joints, mut mapped_acts) = (BTreeSet::new(), BTreeSet::new());
    let mut servo: Option<(String, f64, f64)> = None;
    let mut torque_limits = Vec::with_capacity(n);
    for (name, &j) in dof_names.iter().zip(robot.dof_joints()) {
        let m = map.joints.get(name).ok_or_else(|| {
            map_err(
                "joints",
                format!("the URDF's movable joint `{name}` is not mapped"),
            )
        })?;
        let mj = find(&model, MjtObjBase::mjOBJ_JOINT, "joint", &m.joint)?;
        let expected = match robot.joints()[j].kind {
            JointKind::Prismatic => MjtJoint::mjJNT_SLIDE,
            _ => MjtJoint::mjJNT_HINGE,
        };
        if model.jnt_type()[mj] != expected {
            return Err(map_err(
                format!("joints.{name}.joint"),
                format!(
                    "scene joint `{}` is not a {} joint like the URDF's",
                    m.joint,
                    if expected == MjtJoint::mjJNT_SLIDE {
                        "slide"
                    } else {
                        "hinge"
                    }
                ),
            ));
        }
        let a = find(&model, MjtObjBase::mjOBJ_ACTUATOR, "actuator", &m.actuator)?;
        let (kp, kv) = position_servo(&model, a, mj, &m.actuator, &m.joint)?;
        match &servo {
            None => servo = Some((m.actuator.clone(), kp, kv)),
            Some((first, kp0, _)) if (kp - kp0).abs() > 1e-9 * kp0.abs() => {
                return Err(servo_err(
                    &m.actuator,
                    format!(
                        "kp {kp} N·m/rad differs from `{first}`'s {kp0}: the sag compensation uses one stiffness"
                    ),
                ));
            }
            Some(_) => {}
        }
        torque_limits.push(
            model.actuator_forcelimited()[a]
                .then(|| model.actuator_forcerange()[a])
                .filter(|r| r[0] == -r[1])
                .map(|r| r[1]),
        );
        mapped_joints.insert(mj);
        mapped_acts.insert(a);
        qpos_adr.push(model.jnt_qposadr()[mj] as usize);
        dof_adr.push(model.jnt_dofadr()[mj] as usize);
        actuator.push(a);
    }
    if let Some(j) = (0..model.jnt_type().len()).find(|&j| j != free && !mapped_joints.contains(&j))
    {
        return Err(map_err(
            "joints",
            format!(
                "scene joint `{}` is not in the joint map: it would move unseen",
                name_of(&model, MjtObjBase::mjOBJ_JOINT, j)
            ),
        ));
    }
    if let Some(a) = (0..model.actuator_trntype().len()).find(|a| !mapped_acts.contains(a)) {
        return Err(map_err(
            "joints",
            format!(
                "scene actuator `{}` is not in the joint map: it would push unseen",
                name_of(&model, MjtObjBase::mjOBJ_ACTUATOR, a)
            ),
        ));
    }

    // Soles and floor.
    let mut sole_geoms = [0; 2];
    for side in Side::BOTH {
        let k = side.index();
        sole_geoms[k] = match map.soles.get(&foot_names[k]) {
            Some(g) => {
                let id = find(&model, MjtObjBase::mjOBJ_GEOM, "geom", g)?;
                if model.geom_bodyid()[id] as usize != foot_bodies[k]
                    || model.geom_type()[id] != MjtGeomBase::mjGEOM_BOX
                {
                    return Err(map_err(
                        format!("soles.{}", foot_names[k]),
                        format!(
                            "geom `{g}` is not a box on the foot body `{}`",
                            name_of(&model, MjtObjBase::mjOBJ_BODY, foot_bodies[k])
                        ),
                    ));
                }
                id
            }
            None => sole_geom(&model, foot_bodies[k], biped, side)?,
        };
    }
    let floor_geom = match &map.floor_geom {
        Some(g) => find(&model, MjtObjBase::mjOBJ_GEOM, "geom", g)?,
        None => {
            let planes: Vec<usize> = (0..model.geom_type().len())
                .filter(|&g| {
                    model.geom_bodyid()[g] == 0 && model.geom_type()[g] == MjtGeomBase::mjGEOM_PLANE
                })
                .collect();
            match planes.as_slice() {
                [g] => *g,
                _ => {
                    return Err(map_err(
                        "floor_geom",
                        format!(
                            "the world body has {} plane geoms; name the floor",
                            planes.len()
                        ),
                    ));
                }
            }
        }
    };

    let (_, kp, kv) = servo.ok_or_else(|| map_err("joints", "no joints"))?;
    let first_limit = torque_limits.first().copied().flatten();
    let timestep_s = model.opt().timestep;
    let effective = SimConfig {
        kp_nm_per_rad: kp,
        kv_nm_s_per_rad: kv,
        torque_limit_nm: first_limit.filter(|l| torque_limits.iter().all(|t| *t == Some(*l))),
        armature_kg_m2: dof_adr.first().map_or(0.0, |&d| model.dof_armature()[d]),
        timestep_s,
        friction: model.geom_friction()[sole_geoms[0]][0],
        ..cfg.clone()
    };
    if !(timestep_s.is_finite() && timestep_s > 0.0) {
        return Err(map_err(
            "(scene)",
            format!("timestep {timestep_s} s is not positive"),
        ));
    }
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
        floor_geom,
        warnings,
    };
    Ok((Arc::new(model), layout, effective))
}

/// Checks that actuator `a` is a plain position servo on joint `j`; returns its kp and kv.
fn position_servo(
    model: &MjModel,
    a: usize,
    j: usize,
    name: &str,
    joint: &str,
) -> Result<(f64, f64), SimError> {
    if model.actuator_trntype()[a] != MjtTrn::mjTRN_JOINT
        || model.actuator_trnid()[a][0] as usize != j
    {
        return Err(servo_err(name, format!("does not drive joint `{joint}`")));
    }
    if model.actuator_gear()[a][0] != 1.0 {
        return Err(servo_err(
            name,
            format!(
                "gear {} (a servo target is the joint angle: gear 1)",
                model.actuator_gear()[a][0]
            ),
        ));
    }
    if model.actuator_dyntype()[a] != MjtDyn::mjDYN_NONE {
        return Err(servo_err(
            name,
            "has activation dynamics (a filtered or integrated actuator); a position servo has none",
        ));
    }
    let g = model.actuator_gainprm()[a];
    let b = model.actuator_biasprm()[a];
    let (kp, kv) = (g[0], -b[2]);
    let plain = model.actuator_gaintype()[a] == MjtGain::mjGAIN_FIXED
        && model.actuator_biastype()[a] == MjtBias::mjBIAS_AFFINE
        && kp.is_finite()
        && kp > 0.0
        && b[0] == 0.0
        && (b[1] + kp).abs() <= 1e-12 * kp
        && kv.is_finite()
        && kv >= 0.0;
    if !plain {
        return Err(servo_err(
            name,
            format!(
                "is not a position servo (force = kp·(target − q) − kv·q̇): gain {:?} {:?}, bias {:?} {:?}",
                model.actuator_gaintype()[a],
                &g[..3],
                model.actuator_biastype()[a],
                &b[..3]
            ),
        ));
    }
    Ok((kp, kv))
}
