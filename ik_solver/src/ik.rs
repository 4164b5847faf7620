//! The paper's closed-form leg IK (ALGORITHM.md, "Leg IK, corrected"), mapped to each URDF
//! joint's axis sign and zero pose.
//!
//! A target is the ankle point (where the ankle axes cross) relative to the leg's hip point
//! (where the hip yaw and roll axes cross), in base-frame axes, plus a foot yaw for 6-joint
//! legs. The sole is kept level and, on 6-joint legs, turned by the yaw. Sideways and forward
//! offsets between the axes (the leg layouts of servo humanoids) stay in closed form
//! (ALGORITHM.md, "Leg layouts of real servo humanoids"). No iteration: per leg, two square
//! roots and three `atan2` (the paper's `atan2`/`asin`/`acos` terms summed by the angle-sum
//! identities), both legs side by side in SIMD lanes.
//!
//! Unreachable targets are pulled onto the reachable boundary and joint-limit violations are
//! clamped; both are reported as [`IkIssue`]s naming the leg, the joint and the amount.
//! A non-finite target is refused with an [`IkError`]: NaN never leaves the solver.

use std::f64::consts::PI;
use std::fmt;

use nalgebra::{Isometry3, Vector3};
use wide::f64x2;

use crate::error::{IkError, ModelError, ParameterFilesError};
use crate::legs::{JointRole, Leg, LegJoint, LegRoleMap, Side, find_legs, find_legs_all};
use crate::model::RobotModel;
use crate::trig::atan2_x2;

/// Overshoot of the reach (m) taken as rounding of a straight leg, not reported.
pub const REACH_TOLERANCE_M: f64 = 1e-12;

/// Targets farther than this from the hip (m) are brought to this distance along their
/// direction before solving: far beyond any leg, and short of where the squared lengths the
/// solver works with would overflow. The leg is stretched toward them either way; the angles
/// differ by less than e / `FAR_M` (a few nanoradians).
pub const FAR_M: f64 = 1e6;

/// Where one ankle should be.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnkleTarget {
    /// Ankle point relative to the hip point, base-frame axes (m) (see [`Leg`](crate::Leg)).
    pub ankle_in_hip_m: Vector3<f64>,
    /// Foot yaw relative to the base (rad); must be 0 on 5-joint legs.
    pub foot_yaw_rad: f64,
}

impl AnkleTarget {
    /// A target with the foot straight ahead.
    pub fn new(x_m: f64, y_m: f64, z_m: f64) -> Self {
        Self {
            ankle_in_hip_m: Vector3::new(x_m, y_m, z_m),
            foot_yaw_rad: 0.0,
        }
    }
}

/// Something the solver had to change to give a safe answer.
#[derive(Debug, Clone, PartialEq)]
pub enum IkIssue {
    /// The target is farther from the hip pitch axis than the stretched leg reaches.
    OutOfReach {
        /// Which leg.
        side: Side,
        /// Distance asked for (m).
        distance_m: f64,
        /// The leg's reach (m).
        reach_m: f64,
    },
    /// The target is closer to the hip pitch axis than the folded leg allows.
    TooClose {
        /// Which leg.
        side: Side,
        /// Distance asked for (m).
        distance_m: f64,
        /// The shortest distance the leg can make (m).
        min_m: f64,
    },
    /// A joint angle beyond its URDF limit was clamped to the limit.
    JointLimit {
        /// Which leg.
        side: Side,
        /// Which joint role.
        role: JointRole,
        /// The URDF joint name.
        joint: String,
        /// The angle the target needed (rad).
        requested_rad: f64,
        /// The angle sent instead (rad).
        clamped_rad: f64,
    },
    /// The target is closer to the hip roll axis than the leg's sideways offset e between
    /// the roll axis and the ankle point: no roll puts the ankle there.
    InsideLateralOffset {
        /// Which leg.
        side: Side,
        /// Distance asked for, from the hip roll axis (m).
        distance_m: f64,
        /// The leg's sideways offset e (m).
        offset_m: f64,
    },
    /// A foot yaw was asked of a leg without a hip yaw joint; 0 was used.
    NoYawJoint {
        /// Which leg.
        side: Side,
        /// The yaw asked for (rad).
        requested_rad: f64,
    },
}

impl fmt::Display for IkIssue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            IkIssue::OutOfReach {
                side,
                distance_m,
                reach_m,
            } => write!(
                f,
                "{side} leg: ankle target {distance_m:.4} m from the hip pitch axis is beyond the leg's reach {reach_m:.4} m by {:.4} m; pulled onto the reach",
                distance_m - reach_m
            ),
            IkIssue::TooClose {
                side,
                distance_m,
                min_m,
            } => write!(
                f,
                "{side} leg: ankle target {distance_m:.4} m from the hip pitch axis is closer than the folded leg allows ({min_m:.4} m) by {:.4} m; pushed out",
                min_m - distance_m
            ),
            IkIssue::JointLimit {
                side,
                role,
                joint,
                requested_rad,
                clamped_rad,
            } => write!(
                f,
                "{side} leg: {role} joint `{joint}` needs {requested_rad:.4} rad, beyond its limit by {:.4} rad; clamped to {clamped_rad:.4} rad",
                (requested_rad - clamped_rad).abs()
            ),
            IkIssue::InsideLateralOffset {
                side,
                distance_m,
                offset_m,
            } => write!(
                f,
                "{side} leg: ankle target {distance_m:.4} m from the hip roll axis is inside the leg's sideways offset {:.4} m; the leg was laid sideways",
                offset_m.abs()
            ),
            IkIssue::NoYawJoint {
                side,
                requested_rad,
            } => {
                write!(
                    f,
                    "{side} leg: foot yaw {requested_rad:.4} rad asked of a leg without a hip yaw joint; 0 used"
                )
            }
        }
    }
}

/// One leg's joint angles, by [`JointRole`] (URDF convention: the angle to send to the joint).
#[derive(Debug, Clone, PartialEq)]
pub struct LegSolution {
    /// Which leg.
    pub side: Side,
    /// Angle of each role (rad); the yaw entry is 0 on 5-joint legs.
    pub angles_rad: [f64; 6],
    /// What was clamped, empty when the target was solved exactly.
    pub issues: Vec<IkIssue>,
}

impl LegSolution {
    /// The angle of a role (rad).
    pub fn angle(&self, role: JointRole) -> f64 {
        self.angles_rad[role as usize]
    }
    /// True when the target was solved exactly, without clamping.
    pub fn is_exact(&self) -> bool {
        self.issues.is_empty()
    }
}

/// A biped robot: its kinematic tree and its two legs.
#[derive(Debug, Clone)]
pub struct BipedModel {
    robot: RobotModel,
    legs: [Leg; 2],
    /// Each leg's joints as the solver's last step reads them (from `legs`).
    roles: [RoleTable; 2],
}

/// One leg's joints by [`JointRole`], laid out for the solver's last step: axis signs, limits
/// and joint-vector slots; a role without a joint has sign 1, no limits and no slot.
#[derive(Debug, Clone, Copy)]
struct RoleTable {
    sign: [f64; 6],
    lower_rad: [f64; 6],
    upper_rad: [f64; 6],
    /// Index in the joint vector; `usize::MAX` (no slot) for a role without a joint.
    dof: [usize; 6],
}

impl RoleTable {
    fn of(leg: &Leg) -> Self {
        let mut t = Self {
            sign: [1.0; 6],
            lower_rad: [f64::NEG_INFINITY; 6],
            upper_rad: [f64::INFINITY; 6],
            dof: [usize::MAX; 6],
        };
        for (role, joint) in leg.present() {
            let i = role as usize;
            t.sign[i] = joint.axis_sign;
            t.lower_rad[i] = joint.limits.lower;
            t.upper_rad[i] = joint.limits.upper;
            t.dof[i] = joint.dof;
        }
        t
    }
}

fn check_finite(side: Side, field: &'static str, value: f64) -> Result<(), IkError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(IkError::NonFiniteTarget { side, field, value })
    }
}

impl BipedModel {
    /// Builds the model from a URDF document, finding the legs by their joint axes.
    ///
    /// ```
    /// use ik_solver::{AnkleTarget, BipedModel, JointRole, Side};
    /// let urdf = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../config/biped.urdf")).unwrap();
    /// let biped = BipedModel::from_urdf_str(&urdf, None).unwrap();
    /// // Ankle straight below the hip, 2 cm short of the stretched leg: the knee bends.
    /// let reach = biped.leg(Side::Left).max_reach_m();
    /// let sol = biped.solve_leg(Side::Left, &AnkleTarget::new(0.0, 0.0, -(reach - 0.02))).unwrap();
    /// assert!(sol.is_exact() && sol.angle(JointRole::Knee).abs() > 0.1);
    /// ```
    pub fn from_urdf_str(urdf: &str, role_map: Option<&LegRoleMap>) -> Result<Self, ModelError> {
        Self::from_robot(RobotModel::from_urdf_str(urdf)?, role_map)
    }

    /// Reads a URDF file: see [`Self::from_urdf_str`].
    pub fn from_urdf_file(
        path: impl AsRef<std::path::Path>,
        role_map: Option<&LegRoleMap>,
    ) -> Result<Self, ModelError> {
        Self::from_robot(RobotModel::from_urdf_file(path)?, role_map)
    }

    /// The robot of a `robot_description_file` parameter: a URDF path, or the built-in
    /// default robot for an empty string.
    pub fn from_file_or_default(
        path: &str,
        role_map: Option<&LegRoleMap>,
    ) -> Result<Self, ModelError> {
        if path.is_empty() {
            Self::from_urdf_str(crate::DEFAULT_URDF, role_map)
        } else {
            Self::from_urdf_file(path, role_map)
        }
    }

    /// Builds the model from a URDF document, or lists every problem found in it (never an
    /// empty list): each link and joint, the tree, then both legs, for a user fixing their
    /// robot's description (`biped check-robot`).
    pub fn from_urdf_str_all(
        urdf: &str,
        role_map: Option<&LegRoleMap>,
    ) -> Result<Self, Vec<ModelError>> {
        let parsed =
            urdf_rs::read_from_string(urdf).map_err(|e| vec![ModelError::Parse(e.to_string())])?;
        let robot = RobotModel::from_urdf_all(&parsed)?;
        let legs = find_legs_all(&robot, role_map)?;
        Ok(Self::with_legs(robot, legs))
    }

    /// The robot of a node's `robot_description_file` and `leg_map_file` parameters: a URDF
    /// path (empty: the built-in robot) and a leg map path (empty: legs found by their axes).
    /// Errors name both parameters and their values.
    pub fn from_parameter_files(
        robot_file: &str,
        leg_map_file: &str,
    ) -> Result<Self, ParameterFilesError> {
        LegRoleMap::from_file_or_none(leg_map_file)
            .and_then(|map| Self::from_file_or_default(robot_file, map.as_ref()))
            .map_err(|source| ParameterFilesError {
                robot_file: robot_file.to_string(),
                leg_map_file: leg_map_file.to_string(),
                source,
            })
    }

    /// Finds the legs of an already parsed tree.
    pub fn from_robot(
        robot: RobotModel,
        role_map: Option<&LegRoleMap>,
    ) -> Result<Self, ModelError> {
        let legs = find_legs(&robot, role_map)?;
        Ok(Self::with_legs(robot, legs))
    }

    fn with_legs(robot: RobotModel, legs: [Leg; 2]) -> Self {
        let roles = legs.each_ref().map(RoleTable::of);
        Self { robot, legs, roles }
    }

    /// The whole kinematic tree (FK, CoM, all joints).
    pub fn robot(&self) -> &RobotModel {
        &self.robot
    }

    /// One leg.
    pub fn leg(&self, side: Side) -> &Leg {
        &self.legs[side.index()]
    }

    /// The joints of both legs, left then right, each hip to foot, with their leg's side.
    pub fn leg_joints(&self) -> impl Iterator<Item = (Side, &LegJoint)> {
        Side::BOTH
            .into_iter()
            .flat_map(move |s| self.leg(s).present().map(move |(_, j)| (s, j)))
    }

    /// Solves one leg.
    pub fn solve_leg(&self, side: Side, target: &AnkleTarget) -> Result<LegSolution, IkError> {
        // The leg in both SIMD lanes; the second lane's copy of the answer is not used.
        let (mut issues, mut unused) = (Vec::new(), Vec::new());
        let [angles_rad, _] =
            self.solve_pair([side, side], [target, target], [&mut issues, &mut unused])?;
        Ok(LegSolution {
            side,
            angles_rad,
            issues,
        })
    }

    /// Solves both legs and writes their angles into the joint vector `q` (other joints are
    /// left as they are). Returns what was clamped, for both legs (empty, unallocated, when
    /// both targets were solved exactly).
    pub fn solve_legs(
        &self,
        left: &AnkleTarget,
        right: &AnkleTarget,
        q: &mut [f64],
    ) -> Result<Vec<IkIssue>, IkError> {
        if q.len() != self.robot.dof_count() {
            return Err(IkError::JointCount {
                expected: self.robot.dof_count(),
                got: q.len(),
            });
        }
        // Solve both before writing either: a refused target leaves `q` untouched.
        let (mut issues, mut right_issues) = (Vec::new(), Vec::new());
        let [l, r] = self.solve_pair(
            [Side::Left, Side::Right],
            [left, right],
            [&mut issues, &mut right_issues],
        )?;
        // The left leg's issues first, as when each leg is solved on its own.
        issues.append(&mut right_issues);
        self.write_angles(Side::Left, &l, q);
        self.write_angles(Side::Right, &r, q);
        Ok(issues)
    }

    /// Two legs' angles by [`JointRole`] (or one leg's twice), side by side in SIMD lanes;
    /// what had to be clamped is appended to each lane's `issues` (nothing is allocated when
    /// nothing is clamped). A non-finite target is refused, the first lane's first.
    ///
    /// The paper's angles are sums and differences of `atan2`, `asin` and `acos` terms; each
    /// sum is taken here as one `atan2` of the summed sine and cosine (the angle-sum
    /// identities), with the quadrant of the separate terms restored, so a leg costs three
    /// inverse tangents and two square roots instead of nine transcendental calls. The answer
    /// is the same to rounding (`ik_properties.rs` checks it against the textbook form). The
    /// two legs go through the geometry and the inverse tangents together, two lanes of each
    /// operation ([`crate::trig`]); what is rare (a target out of reach, a clamped joint) is
    /// done lane by lane off that path.
    #[inline(always)]
    fn solve_pair(
        &self,
        sides: [Side; 2],
        targets: [&AnkleTarget; 2],
        issues: [&mut Vec<IkIssue>; 2],
    ) -> Result<[[f64; 6]; 2], IkError> {
        let [issues0, issues1] = issues;
        let t0 = self.target_in_hip_frame(sides[0], targets[0], issues0)?;
        let t1 = self.target_in_hip_frame(sides[1], targets[1], issues1)?;
        let issues = [issues0, issues1];
        let legs = sides.map(|s| self.leg(s));
        let lanes = |f: fn(&Leg) -> f64| f64x2::new([f(legs[0]), f(legs[1])]);
        let (px, py, pz) = (
            f64x2::new([t0.p[0], t1.p[0]]),
            f64x2::new([t0.p[1], t1.p[1]]),
            f64x2::new([t0.p[2], t1.p[2]]),
        );
        let zero = f64x2::ZERO;

        // Hip roll turns the leg's plane, which keeps the distance e from the roll axis,
        // until it contains the ankle: the tangent from the ankle to the circle of radius e
        // (ALGORITHM.md, "Leg layouts of real servo humanoids"). With e = 0 it is the
        // paper's atan2(y, -z).
        let e = lanes(|l| l.ankle_lateral_m);
        let r2 = py * py + pz * pz;
        // The reach within the leg's plane, down from the roll axis: the tangent's length
        // sqrt(r^2 - e^2) (with e = 0, r itself); and sin asin(e / r) = e / r, times r.
        // Inside the circle: asin(+-1), the leg laid sideways (a positive factor of r left
        // out).
        let inside = r2.simd_lt(e * e);
        if inside.any() {
            let (r2, e) = (r2.to_array(), e.to_array());
            for i in 0..2 {
                if r2[i] < e[i] * e[i] {
                    issues[i].push(IkIssue::InsideLateralOffset {
                        side: sides[i],
                        distance_m: r2[i].sqrt(),
                        offset_m: e[i],
                    });
                }
            }
        }
        let in_plane = inside.select(zero, (r2 - e * e).sqrt());
        let e_r = inside.select(f64x2::ONE.copysign(e), e);
        // roll = atan2(y, -z) - asin(e / r), as one atan2 of the difference's sine and cosine
        // (times r), on the branch of atan2(y, -z). On the roll axis itself, no roll
        // (atan2(0, 1)).
        let off_axis = r2.simd_gt(zero);
        let roll_y = off_axis.select(py * in_plane + pz * e_r, zero);
        let roll_x = off_axis.select(py * e_r - pz * in_plane, f64x2::ONE);
        // The pitch axis sits `hip_roll_to_pitch_m` below the roll axis and
        // `hip_pitch_forward_m` ahead of the hip.
        let mut x = px - lanes(|l| l.hip_pitch_forward_m);
        let mut z = in_plane - lanes(|l| l.hip_roll_to_pitch_m);

        // The triangle hip pitch - knee - ankle pitch; its reach compared in squared lengths.
        let (l1, l2) = (lanes(|l| l.thigh_m), lanes(|l| l.shin_m));
        let (reach, fold) = (l1 + l2, l1 - l2);
        let mut d2 = x * x + z * z;
        let min = fold.abs().max(f64x2::splat(1e-6) * reach);
        if (d2.simd_gt(reach * reach) | d2.simd_lt(min * min)).any() {
            let (mut xs, mut zs, mut d2s) = (x.to_array(), z.to_array(), d2.to_array());
            for i in 0..2 {
                (xs[i], zs[i], d2s[i]) = bring_within_reach(
                    legs[i],
                    [t0.far, t1.far][i],
                    xs[i],
                    zs[i],
                    d2s[i],
                    issues[i],
                );
            }
            (x, z, d2) = (f64x2::new(xs), f64x2::new(zs), f64x2::new(d2s));
        }
        // The triangle's sines from its area A (Heron's formula, factored so that a leg near
        // its stretch or its fold loses no digits): 4 A = 2 l1 l2 sin(gamma) = 2 l1 d sin(beta)
        // = sqrt((d + l2 - l1)(l1 + l2 - d)(d + l1 - l2)(l1 + l2 + d))
        // = sqrt(((l1 + l2)^2 - d^2)(d^2 - (l1 - l2)^2)), gamma the knee's inner angle, beta
        // the angle at the hip between the thigh and the line to the ankle. Each difference of
        // squares is as exact as the product of its factors (both err by a rounding of the
        // squares) and needs no d, so no square root waits for another here. Their cosines
        // times the same factors by the law of cosines. An acos of the cosine alone would turn
        // a rounding of it into 1e-8 rad near the stretched leg.
        let area4 = ((reach * reach - d2) * (d2 - fold * fold)).max(zero).sqrt();
        let (sin_b, cos_b) = (area4, l1 * l1 + d2 - l2 * l2);
        let roll = atan2_x2(roll_y, roll_x).to_array();
        // The knee's inner angle.
        let gamma = atan2_x2(area4, l1 * l1 + l2 * l2 - d2).to_array();
        // Forward angle of the thigh from straight down: atan2(x, z) + beta as one atan2, on
        // the branch of atan2(x, z).
        let thigh = atan2_x2(x * cos_b + z * sin_b, z * cos_b - x * sin_b).to_array();
        let (py_negative, x_negative) = (
            py.is_sign_negative().to_bitmask(),
            x.is_sign_negative().to_bitmask(),
        );
        let (yaw, mut angles) = ([t0.yaw, t1.yaw], [[0.0; 6]; 2]);
        for (i, issues) in issues.into_iter().enumerate() {
            angles[i] = self.leg_angles(
                sides[i],
                yaw[i],
                unwrap_difference(roll[i], py_negative >> i & 1 != 0),
                gamma[i],
                unwrap_sum(thigh[i], x_negative >> i & 1 != 0),
                issues,
            );
        }
        Ok(angles)
    }

    /// A target checked and turned into the leg's hip frame: the ankle point (brought in from
    /// beyond [`FAR_M`] by the factor `far`) and the foot yaw used.
    #[inline(always)]
    fn target_in_hip_frame(
        &self,
        side: Side,
        target: &AnkleTarget,
        issues: &mut Vec<IkIssue>,
    ) -> Result<HipFrameTarget, IkError> {
        let leg = self.leg(side);
        let p = target.ankle_in_hip_m;
        check_finite(side, "ankle_in_hip.x", p.x)?;
        check_finite(side, "ankle_in_hip.y", p.y)?;
        check_finite(side, "ankle_in_hip.z", p.z)?;
        check_finite(side, "foot_yaw", target.foot_yaw_rad)?;
        let far = p.amax() / FAR_M;
        let (p, far) = if far > 1.0 { (p / far, far) } else { (p, 1.0) };

        let yaw = if leg.has_yaw() {
            target.foot_yaw_rad
        } else {
            if target.foot_yaw_rad != 0.0 {
                issues.push(IkIssue::NoYawJoint {
                    side,
                    requested_rad: target.foot_yaw_rad,
                });
            }
            0.0
        };
        // Into the yawed hip frame (a turn by -yaw about z); the yaw axis passes through the
        // hip point.
        let (px, py) = if yaw == 0.0 {
            (p.x, p.y)
        } else {
            let (sin, cos) = yaw.sin_cos();
            (cos * p.x + sin * p.y, cos * p.y - sin * p.x)
        };
        Ok(HipFrameTarget {
            p: [px, py, p.z],
            yaw,
            far,
        })
    }

    /// One leg's joint angles from its yaw, roll, knee's inner angle gamma and thigh angle,
    /// clamped to the joint limits; what had to be clamped is appended to `issues`.
    #[inline(always)]
    fn leg_angles(
        &self,
        side: Side,
        yaw: f64,
        roll: f64,
        gamma: f64,
        thigh: f64,
        issues: &mut Vec<IkIssue>,
    ) -> [f64; 6] {
        let leg = self.leg(side);
        let shin = thigh - (PI - gamma); // forward angle of the shin

        // To URDF joint angles: a positive rotation about +y swings what hangs below backward.
        let (t0, s0) = (leg.thigh_angle0_rad, leg.shin_angle0_rad);
        // By role: hip yaw, hip roll, hip pitch, knee, ankle pitch, ankle roll.
        let mut angles = [
            yaw,
            roll,
            t0 - thigh,
            (thigh - shin) - (t0 - s0),
            shin - s0,
            -roll,
        ];
        let t = &self.roles[side.index()];
        let mut within = true;
        for (i, a) in angles.iter_mut().enumerate() {
            *a *= t.sign[i];
            within &= *a >= t.lower_rad[i] && *a <= t.upper_rad[i];
        }
        if !within {
            self.clamp_to_limits(side, &mut angles, issues);
        }
        angles
    }

    /// Clamps the angles of a leg to its joints' limits, appending each to `issues`.
    #[cold]
    fn clamp_to_limits(&self, side: Side, angles: &mut [f64; 6], issues: &mut Vec<IkIssue>) {
        for (role, joint) in self.leg(side).present() {
            let a = &mut angles[role as usize];
            if !(joint.limits.lower..=joint.limits.upper).contains(a) {
                let clamped = joint.limits.clamp(*a);
                issues.push(IkIssue::JointLimit {
                    side,
                    role,
                    joint: joint.name.clone(),
                    requested_rad: *a,
                    clamped_rad: clamped,
                });
                *a = clamped;
            }
        }
    }

    /// Writes one leg's angles into a joint vector.
    pub fn write_leg(&self, sol: &LegSolution, q: &mut [f64]) {
        self.write_angles(sol.side, &sol.angles_rad, q);
    }

    fn write_angles(&self, side: Side, angles_rad: &[f64; 6], q: &mut [f64]) {
        for (&dof, &a) in self.roles[side.index()].dof.iter().zip(angles_rad) {
            if let Some(slot) = q.get_mut(dof) {
                *slot = a;
            }
        }
    }

    /// Forward kinematics of the legs: each ankle's position relative to its hip point, in
    /// base-frame axes, for a joint vector. The inverse of [`Self::solve_legs`].
    pub fn ankles_in_hips(&self, q: &[f64]) -> Result<[Vector3<f64>; 2], IkError> {
        let poses = self.robot.link_poses(&Isometry3::identity(), q)?;
        Ok(Side::BOTH.map(|s| {
            let leg = self.leg(s);
            leg.ankle_world(&self.robot, &poses).coords - leg.hip_in_base_m
        }))
    }
}

/// A target in the leg's hip frame (see [`BipedModel::target_in_hip_frame`]).
#[derive(Debug, Clone, Copy)]
struct HipFrameTarget {
    /// The ankle point in the yawed hip frame (m).
    p: [f64; 3],
    /// The foot yaw used (rad): 0 on a leg without a yaw joint.
    yaw: f64,
    /// The factor the target was brought in by from beyond [`FAR_M`] (1 when it was not).
    far: f64,
}

/// The ankle at (x, z) from the hip pitch axis, d2 = x^2 + z^2, brought onto the reach of a
/// leg when beyond it or out to the folded leg's shortest distance when inside that, with the
/// issue appended; otherwise as it is. `far`: the factor the target was brought in by, for the
/// distance reported.
#[cold]
fn bring_within_reach(
    leg: &Leg,
    far: f64,
    x: f64,
    z: f64,
    d2: f64,
    issues: &mut Vec<IkIssue>,
) -> (f64, f64, f64) {
    let (l1, l2) = (leg.thigh_m, leg.shin_m);
    let reach = l1 + l2;
    let min = (l1 - l2).abs().max(1e-6 * reach);
    let side = leg.side;
    if d2 > reach * reach {
        let d = d2.sqrt();
        // Straight legs land here by rounding; only a real overshoot is an issue.
        if d > reach + REACH_TOLERANCE_M {
            issues.push(IkIssue::OutOfReach {
                side,
                // As asked, for a target brought in from beyond `FAR_M`.
                distance_m: d * far,
                reach_m: reach,
            });
        }
        (x * reach / d, z * reach / d, reach * reach)
    } else if d2 < min * min {
        let d = d2.sqrt();
        issues.push(IkIssue::TooClose {
            side,
            distance_m: d,
            min_m: min,
        });
        let (x, z) = if d > 0.0 {
            (x * min / d, z * min / d)
        } else {
            (0.0, min)
        };
        (x, z, min * min)
    } else {
        (x, z, d2)
    }
}

/// An angle difference atan2(y, x) - psi with psi in [-pi/2, pi/2], computed as one atan2 in
/// (-pi, pi], back on the branch the separate terms give: from atan2(y, x) in [0, pi] (y of
/// positive sign) the difference lies in [-pi/2, 3pi/2], from (-pi, 0) in (-3pi/2, pi/2).
fn unwrap_difference(a: f64, y_negative: bool) -> f64 {
    if y_negative {
        if a > 0.5 * PI { a - 2.0 * PI } else { a }
    } else if a < -0.5 * PI {
        a + 2.0 * PI
    } else {
        a
    }
}

/// An angle sum atan2(y, x) + beta with beta in [0, pi], computed as one atan2 in (-pi, pi],
/// back on the branch the separate terms give: from atan2(y, x) in [0, pi] (y of positive
/// sign) the sum lies in [0, 2pi]; from (-pi, 0) in (-pi, pi), where atan2 already is.
fn unwrap_sum(a: f64, y_negative: bool) -> f64 {
    if !y_negative && a < 0.0 {
        a + 2.0 * PI
    } else {
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The branch of each fused angle, by hand: the one atan2 of the combined sine and cosine
    /// wraps into (-pi, pi]; the helpers put it back where the separate terms are.
    #[test]
    fn fused_angles_come_back_on_the_branch_of_their_terms() {
        let wrap = |t: f64| t.sin().atan2(t.cos());
        // atan2(y, x) = 3.0 (y > 0) plus beta = 0.5: 3.5, which atan2 gives as 3.5 - 2 pi.
        assert!((unwrap_sum(wrap(3.5), false) - 3.5).abs() < 1e-12);
        assert!((unwrap_sum(wrap(1.2), false) - 1.2).abs() < 1e-12);
        // From atan2(y, x) = -2.5 (y < 0): -2.5 + 3.0 = 0.5 needs nothing.
        assert!((unwrap_sum(wrap(0.5), true) - 0.5).abs() < 1e-12);
        assert!((unwrap_sum(wrap(-2.9), true) + 2.9).abs() < 1e-12);
        // Differences: 3.0 - (-0.4) = 3.4 (y > 0); -3.0 - 0.4 = -3.4 (y < 0).
        assert!((unwrap_difference(wrap(3.4), false) - 3.4).abs() < 1e-12);
        assert!((unwrap_difference(wrap(-3.4), true) + 3.4).abs() < 1e-12);
        // Inside (-pi/2, pi/2) both are left alone.
        assert!((unwrap_difference(wrap(-1.0), false) + 1.0).abs() < 1e-12);
        assert!((unwrap_difference(wrap(1.0), true) - 1.0).abs() < 1e-12);
    }
}
