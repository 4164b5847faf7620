//! Gait parameters: the YAML file a user edits (ROS 2 parameter-file layout), their bounds,
//! and the values derived from the robot where a parameter is left at 0 ("auto").
//!
//! ```yaml
//! gait_planner:
//!   ros__parameters:
//!     step_length_m: 0.0   # 0 = auto
//!     control_rate_hz: 100.0
//! ```

use ik_solver::{BipedModel, Side};
use serde::{Deserialize, Serialize};

use crate::error::GaitError;

/// Fractions of the leg length (L1 + L2) used when a length is left at 0.
pub mod auto {
    /// Step length: distance the front foot ends ahead of the other.
    pub const STEP_LENGTH_PER_LEG: f64 = 0.45;
    /// Swing foot lift.
    pub const FOOT_LIFT_PER_LEG: f64 = 0.12;
    /// Hip-pitch-axis to ankle-pitch-axis height while walking.
    pub const HIP_DROP_PER_LEG: f64 = 0.75;
    /// Minimum CoM margin and minimum ZMP margin, as a fraction of the narrower sole side.
    pub const MARGIN_PER_SOLE_WIDTH: f64 = 1.0 / 6.0;
    /// Longest backward step, as a fraction of the forward step length.
    pub const BACK_STEP_PER_STEP: f64 = 1.0;
    /// Longest side step (sideways travel of the body per step), as a fraction of the leg.
    pub const SIDE_STEP_PER_LEG: f64 = 0.1;
    /// Largest turn per step (rad) for robots with hip yaw joints.
    pub const TURN_STEP_RAD: f64 = 0.15;
    /// An auto step limit whose check walk fails is lowered by this many bisections.
    pub const BISECTIONS: u32 = 6;
    /// The durations (s) the fastest-timing search scales from when a duration is left at 0:
    /// shift, step, crouch. Slow enough that the reference walk passes the checks on any
    /// robot whose walk passes at all (the defaults before #16).
    pub const REFERENCE_TIMING_S: [f64; 3] = [2.0, 1.0, 1.0];
}

/// The parameters as written in the YAML file. Lengths left at 0 are derived from the robot
/// (see [`auto`]); [`GaitParams::resolve`] gives the values used.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GaitParams {
    /// How far the front foot ends ahead of the other after a step (m); the swing foot of a
    /// full step travels twice this (the paper's s). 0 = auto (a fraction of the leg,
    /// lowered until the check walk passes).
    pub step_length_m: f64,
    /// Longest backward step (m): how far the swing foot may land behind the stance foot
    /// when `cmd_vel` asks to walk backward. 0 = auto (the forward step length, lowered
    /// until the check walk passes).
    pub back_step_length_m: f64,
    /// Longest side step (m): how far the body may travel sideways per step. The foot on
    /// the side of travel opens by twice this, the other closes back to the standing
    /// width. 0 = auto (0.1 x leg, lowered until the check walk passes).
    pub side_step_m: f64,
    /// Largest turn per step (rad): the foot on the side of the turn turns by twice this,
    /// the other comes back parallel. Needs hip yaw joints (0 on robots without). 0 = auto
    /// (0.15 rad with hip yaw, lowered until the check walks pass).
    pub turn_step_rad: f64,
    /// Duration of each swing (half and full steps) (s). 0 = auto: the fastest the checks
    /// allow ([`GaitParams::with_auto_timing`]).
    pub step_duration_s: f64,
    /// Duration of each CoM shift and of the final centring (s). 0 = auto.
    pub shift_duration_s: f64,
    /// Duration of the initial crouch and of the optional final rise (s). 0 = auto.
    pub crouch_duration_s: f64,
    /// Peak height of the swing foot above the floor (m). 0 = auto.
    pub foot_lift_m: f64,
    /// Height of the hip point (hip roll axis) above the floor while walking (m). 0 = auto.
    pub hip_height_m: f64,
    /// Ticks per second of the plan and of the node's publishing (Hz).
    pub control_rate_hz: f64,
    /// Smallest allowed distance from the CoM's floor projection to the support polygon's
    /// edge (m). 0 = auto.
    pub min_com_margin_m: f64,
    /// Smallest allowed distance from the planned ZMP (cart-table model: the CoM's floor
    /// point moved by its acceleration, [`crate::zmp`]) to the support polygon's edge (m).
    /// 0 = auto (the CoM margin's share of the sole).
    pub min_zmp_margin_m: f64,
    /// How long a pause (the node's `~/pause`) takes to bring the walk to rest along its
    /// path, and a resume to bring it back to speed (s): the plan's clock slows and speeds
    /// up as a minimum-jerk ramp ([`crate::pause`]). 0 = auto: the shortest that keeps the
    /// ZMP within `min_zmp_margin_m` pausing at any tick of the check walks, in whole control
    /// periods. A value set by hand is checked the same way.
    pub pause_brake_time_s: f64,
    /// The servos' damping (N·m·s/rad): torque a servo spends on its own speed, `b·q'`.
    /// With `servo_armature_kg_m2`, the torque budget of the fastest timing
    /// ([`crate::timing`]): static torque + `b·|q'|` + `J·|q''|` within each joint's URDF
    /// effort limit. 0 = unknown (no budget for the speed).
    pub servo_damping_nm_s_per_rad: f64,
    /// The servos' rotor inertia through the gearbox, `J` (kg·m²). 0 = unknown.
    pub servo_armature_kg_m2: f64,
    /// Which foot swings first.
    pub first_foot: Side,
    /// Rise back to straight legs at the end of a walk.
    pub rise_at_end: bool,
    /// A walk driven by velocity commands (`cmd_vel`) ends, with its closing half step at
    /// the next point where the feet can come together, when no command has come for this
    /// long (s): a teleop that dies does not leave the robot walking.
    pub cmd_vel_timeout_s: f64,
}

impl Default for GaitParams {
    fn default() -> Self {
        Self {
            step_length_m: 0.0,
            back_step_length_m: 0.0,
            side_step_m: 0.0,
            turn_step_rad: 0.0,
            step_duration_s: 0.0,
            shift_duration_s: 0.0,
            crouch_duration_s: 0.0,
            foot_lift_m: 0.0,
            hip_height_m: 0.0,
            control_rate_hz: 100.0,
            min_com_margin_m: 0.0,
            min_zmp_margin_m: 0.0,
            pause_brake_time_s: 0.0,
            servo_damping_nm_s_per_rad: 0.0,
            servo_armature_kg_m2: 0.0,
            first_foot: Side::Left,
            rise_at_end: false,
            cmd_vel_timeout_s: 0.5,
        }
    }
}

/// [`GaitParams`] after [`GaitParams::resolve`]: every value concrete (no 0 = auto left) and
/// checked against its bounds and the robot.
pub type GaitConfig = GaitParams;

impl GaitParams {
    /// One control period (s).
    pub fn dt_s(&self) -> f64 {
        1.0 / self.control_rate_hz
    }

    /// Time of one step: a CoM shift and a swing (s). A stride per step over this is the
    /// walking speed.
    pub fn step_period_s(&self) -> f64 {
        self.shift_duration_s + self.step_duration_s
    }
}

/// The leg length the lengths left at 0 scale with (m): thigh + shin (L1 + L2), the shorter
/// leg's.
pub fn leg_length_m(model: &BipedModel) -> f64 {
    Side::BOTH
        .iter()
        .map(|&s| model.leg(s).thigh_m + model.leg(s).shin_m)
        .fold(f64::INFINITY, f64::min)
}

/// The hip height (hip roll axis above the floor, m) with the hip pitch axis `drop_per_leg`
/// leg lengths above the ankle point: ankle-to-sole + hip offset + `drop_per_leg` x leg.
pub fn hip_height_for(model: &BipedModel, drop_per_leg: f64) -> f64 {
    let left = model.leg(Side::Left);
    left.ankle_to_sole_m + left.hip_roll_to_pitch_m + drop_per_leg * leg_length_m(model)
}

fn check(key: &'static str, value: f64, lo: f64, hi: f64, unit: &str) -> Result<f64, GaitError> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(value)
    } else {
        Err(GaitError::Param {
            key,
            value,
            why: format!("must be within [{lo}, {hi}] {unit}"),
        })
    }
}

fn auto_or(
    key: &'static str,
    value: f64,
    derived: f64,
    lo: f64,
    hi: f64,
) -> Result<f64, GaitError> {
    if value == 0.0 {
        check(key, derived, lo, hi, "m (derived from the robot)")
    } else {
        check(key, value, lo, hi, "m (0 = auto)")
    }
}

impl GaitParams {
    /// Parses the `gait_planner` section of a ROS 2 parameter file (also `/gait_planner`,
    /// `<ns>/gait_planner` and the `/**` wildcard, which the specific section overrides).
    /// Sections of other nodes are ignored; unknown keys in ours are refused by name.
    pub fn from_ros_yaml_str(text: &str) -> Result<Self, GaitError> {
        Self::from_ros_yaml(text, None)
    }

    /// Reads a ROS 2 parameter file: see [`Self::from_ros_yaml_str`].
    pub fn from_ros_yaml_file(path: impl AsRef<std::path::Path>) -> Result<Self, GaitError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| GaitError::ParamFile {
            path: Some(path.display().to_string()),
            message: e.to_string(),
        })?;
        Self::from_ros_yaml(&text, Some(path.display().to_string()))
    }

    fn from_ros_yaml(text: &str, path: Option<String>) -> Result<Self, GaitError> {
        let err = |message: String| GaitError::ParamFile {
            path: path.clone(),
            message,
        };
        let doc: serde_norway::Value =
            serde_norway::from_str(text).map_err(|e| err(e.to_string()))?;
        let Some(top) = doc.as_mapping() else {
            return Err(err(
                "the file is not a mapping of node names to `ros__parameters`".into(),
            ));
        };
        let mut merged = serde_norway::Mapping::new();
        let mut found = false;
        // Wildcard first, then the node's own section, so the specific one wins.
        for pass in 0..2 {
            for (k, v) in top {
                let key = k.as_str().unwrap_or_default();
                let ours = key == "gait_planner" || key.ends_with("/gait_planner");
                let wildcard = key == "/**";
                if (pass == 0 && !wildcard) || (pass == 1 && !ours) {
                    continue;
                }
                let Some(params) = v.get("ros__parameters") else {
                    return Err(err(format!("section `{key}` has no `ros__parameters`")));
                };
                let Some(map) = params.as_mapping() else {
                    return Err(err(format!("`{key}.ros__parameters` is not a mapping")));
                };
                found |= ours;
                for (pk, pv) in map {
                    // The wildcard section may hold other nodes' parameters; keep only ours.
                    let name = pk.as_str().unwrap_or_default();
                    if ours || Self::is_known(name) {
                        merged.insert(pk.clone(), pv.clone());
                    }
                }
            }
        }
        if !found && merged.is_empty() {
            return Err(err("no `gait_planner:` section".into()));
        }
        serde_norway::from_value(serde_norway::Value::Mapping(merged))
            .map_err(|e| err(format!("gait_planner.ros__parameters: {e}")))
    }

    /// These parameters as a ROS 2 parameter file (`gait_planner: ros__parameters: ...`,
    /// every key), which [`Self::from_ros_yaml_str`] reads back to the same values.
    pub fn to_ros_yaml_string(&self) -> Result<String, GaitError> {
        let err = |e: serde_norway::Error| GaitError::ParamFile {
            path: None,
            message: e.to_string(),
        };
        let mut section = serde_norway::Mapping::new();
        section.insert(
            "ros__parameters".into(),
            serde_norway::to_value(self).map_err(err)?,
        );
        let mut top = serde_norway::Mapping::new();
        top.insert("gait_planner".into(), serde_norway::Value::Mapping(section));
        serde_norway::to_string(&top).map_err(err)
    }

    fn is_known(name: &str) -> bool {
        serde_norway::to_value(Self::default())
            .ok()
            .and_then(|v| v.as_mapping().map(|m| m.contains_key(name)))
            .unwrap_or(false)
    }

    /// The slow walk of the defaults before #16, for `model`: steps of 0.25 x leg on hips
    /// 0.85 x leg (set explicitly), shift 2 s, step 1 s, crouch 1 s ([`auto::REFERENCE_TIMING_S`]),
    /// the rest as [`Default`]. A third of the default walk's speed (0.013 m/s on the default
    /// robot), with the widest margins: the walk to first try a new robot's hardware with,
    /// and the reference many hand-computed tests are written against.
    pub fn slow(model: &BipedModel) -> GaitParams {
        let [shift, step, crouch] = auto::REFERENCE_TIMING_S;
        GaitParams {
            step_length_m: 0.25 * leg_length_m(model),
            hip_height_m: hip_height_for(model, 0.85),
            shift_duration_s: shift,
            step_duration_s: step,
            crouch_duration_s: crouch,
            ..GaitParams::default()
        }
    }

    /// True when a duration is left at 0 (auto): [`Self::with_auto_timing`] fills it in.
    pub fn has_auto_timing(&self) -> bool {
        [
            self.shift_duration_s,
            self.step_duration_s,
            self.crouch_duration_s,
        ]
        .contains(&0.0)
    }

    /// These parameters with the durations left at 0 (auto) at the timing search's
    /// reference timing.
    fn at_reference_timing(&self) -> GaitParams {
        let pick = |given: f64, auto: f64| if given == 0.0 { auto } else { given };
        GaitParams {
            shift_duration_s: pick(self.shift_duration_s, auto::REFERENCE_TIMING_S[0]),
            step_duration_s: pick(self.step_duration_s, auto::REFERENCE_TIMING_S[1]),
            crouch_duration_s: pick(self.crouch_duration_s, auto::REFERENCE_TIMING_S[2]),
            ..self.clone()
        }
    }

    /// Every parameter's bounds on `model`, without the timing search (which takes 0.3-1.2
    /// s): durations left at 0 (auto) are taken at the search's reference timing.
    /// [`Self::with_auto_timing`] checks the same first; a caller that starts something
    /// before the search (`biped walk` starts the fleet) refuses a bad value with this
    /// before anything starts.
    pub fn check_bounds(&self, model: &BipedModel) -> Result<(), GaitError> {
        self.at_reference_timing().resolve(model).map(|_| ())
    }

    /// These parameters with every duration left at 0 set to the fastest the planning checks
    /// allow for `model` ([`crate::timing::fastest_timing`]: joint speed limits, the ZMP
    /// margin, pausing anywhere within `pause_brake_time_s` or
    /// [`crate::timing::PAUSE_BRAKE_BUDGET_S`], the servos' torque budget when given),
    /// scaled from [`auto::REFERENCE_TIMING_S`] for the ones left at 0 and from the others
    /// as set. The step limits the search verified (forward, back, side, turn) are set explicitly, so
    /// the faster timing never lowers an auto one. Durations set by hand stay as set (and
    /// are checked with the rest by [`crate::GaitPlanner::new`]). With no duration at 0,
    /// the parameters unchanged and no search. Costs one timing search (0.3-1.2 s, a
    /// handful of checked planners: BENCHMARKS.md).
    pub fn with_auto_timing(
        &self,
        model: &BipedModel,
    ) -> Result<(GaitParams, Option<crate::timing::FastestTiming>), GaitError> {
        if !self.has_auto_timing() {
            return Ok((self.clone(), None));
        }
        let given = [
            self.shift_duration_s,
            self.step_duration_s,
            self.crouch_duration_s,
        ];
        let pick = |i: usize, auto: f64| if given[i] == 0.0 { auto } else { given[i] };
        let reference = self.at_reference_timing();
        // Bounds first: a bad value is named as such, not as a failed search.
        reference.resolve(model)?;
        let found = crate::timing::fastest_timing(model, &reference).map_err(|e| {
            GaitError::Request(format!(
                "durations left at 0 (auto): no timing found from the reference shift {} s, step {} s, crouch {} s: {e}",
                reference.shift_duration_s, reference.step_duration_s, reference.crouch_duration_s
            ))
        })?;
        let t = found.timing;
        let filled = GaitParams {
            shift_duration_s: pick(0, t.shift_duration_s),
            step_duration_s: pick(1, t.step_duration_s),
            crouch_duration_s: pick(2, t.crouch_duration_s),
            step_length_m: found.params.step_length_m,
            back_step_length_m: found.params.back_step_length_m,
            side_step_m: found.params.side_step_m,
            turn_step_rad: found.params.turn_step_rad,
            ..self.clone()
        };
        Ok((filled, Some(found)))
    }

    /// Checks every bound and fills in the values left at 0 from the robot (durations by
    /// the timing search of [`Self::with_auto_timing`]).
    pub fn resolve(&self, model: &BipedModel) -> Result<GaitParams, GaitError> {
        if self.has_auto_timing() {
            return self.with_auto_timing(model)?.0.resolve(model);
        }
        let left = model.leg(Side::Left);
        let right = model.leg(Side::Right);
        let leg = leg_length_m(model);
        let sole_width = left
            .sole
            .width_m()
            .min(left.sole.length_m())
            .min(right.sole.width_m())
            .min(right.sole.length_m());
        let hip_lo = hip_height_for(model, 0.5);
        let hip_hi = hip_height_for(model, 1.0);
        let step_length_m = auto_or(
            "step_length_m",
            self.step_length_m,
            auto::STEP_LENGTH_PER_LEG * leg,
            0.0,
            0.6 * leg,
        )?;
        Ok(GaitParams {
            step_length_m,
            back_step_length_m: auto_or(
                "back_step_length_m",
                self.back_step_length_m,
                auto::BACK_STEP_PER_STEP * step_length_m,
                0.0,
                0.6 * leg,
            )?,
            side_step_m: auto_or(
                "side_step_m",
                self.side_step_m,
                auto::SIDE_STEP_PER_LEG * leg,
                0.0,
                0.3 * leg,
            )?,
            turn_step_rad: {
                let has_yaw = Side::BOTH.iter().all(|&s| model.leg(s).has_yaw());
                if !has_yaw && self.turn_step_rad != 0.0 {
                    return Err(GaitError::Param {
                        key: "turn_step_rad",
                        value: self.turn_step_rad,
                        why: "this robot's legs have no hip yaw joint; leave it at 0".into(),
                    });
                }
                let derived = if has_yaw { auto::TURN_STEP_RAD } else { 0.0 };
                let v = if self.turn_step_rad == 0.0 {
                    derived
                } else {
                    self.turn_step_rad
                };
                check("turn_step_rad", v, 0.0, 0.5, "rad (0 = auto)")?
            },
            step_duration_s: check(
                "step_duration_s",
                self.step_duration_s,
                0.1,
                60.0,
                "s (0 = auto)",
            )?,
            shift_duration_s: check(
                "shift_duration_s",
                self.shift_duration_s,
                0.1,
                60.0,
                "s (0 = auto)",
            )?,
            crouch_duration_s: check(
                "crouch_duration_s",
                self.crouch_duration_s,
                0.1,
                60.0,
                "s (0 = auto)",
            )?,
            foot_lift_m: auto_or(
                "foot_lift_m",
                self.foot_lift_m,
                auto::FOOT_LIFT_PER_LEG * leg,
                0.001,
                0.4 * leg,
            )?,
            hip_height_m: auto_or(
                "hip_height_m",
                self.hip_height_m,
                hip_height_for(model, auto::HIP_DROP_PER_LEG),
                hip_lo,
                hip_hi,
            )?,
            control_rate_hz: check("control_rate_hz", self.control_rate_hz, 1.0, 1000.0, "Hz")?,
            min_com_margin_m: auto_or(
                "min_com_margin_m",
                self.min_com_margin_m,
                auto::MARGIN_PER_SOLE_WIDTH * sole_width,
                0.0,
                sole_width,
            )?,
            min_zmp_margin_m: auto_or(
                "min_zmp_margin_m",
                self.min_zmp_margin_m,
                auto::MARGIN_PER_SOLE_WIDTH * sole_width,
                0.0,
                sole_width,
            )?,
            pause_brake_time_s: check(
                "pause_brake_time_s",
                self.pause_brake_time_s,
                0.0,
                10.0,
                "s (0 = auto)",
            )?,
            servo_damping_nm_s_per_rad: check(
                "servo_damping_nm_s_per_rad",
                self.servo_damping_nm_s_per_rad,
                0.0,
                100.0,
                "N·m·s/rad",
            )?,
            servo_armature_kg_m2: check(
                "servo_armature_kg_m2",
                self.servo_armature_kg_m2,
                0.0,
                10.0,
                "kg·m²",
            )?,
            first_foot: self.first_foot,
            rise_at_end: self.rise_at_end,
            cmd_vel_timeout_s: check(
                "cmd_vel_timeout_s",
                self.cmd_vel_timeout_s,
                0.01,
                3600.0,
                "s",
            )?,
        })
    }
}
