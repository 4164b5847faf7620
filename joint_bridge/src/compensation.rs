//! Servo-sag compensation in the command path: position servos are springs
//! (ALGORITHM.md), so under the robot's weight a joint settles torque / kp short of its
//! target. The bridge aims each servo the static torque of the commanded pose / kp further
//! ([`ik_solver::BipedModel::sag_compensation_rad`]: URDF mass model, level base, stance read
//! from the feet's heights), then applies the URDF limits to the result.

use ik_solver::BipedModel;

use crate::limits::JointSpec;

/// Why sag compensation or gyro damping cannot be set up for a bridge.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CompensationError {
    /// The stiffness is not a positive finite number.
    #[error("servo stiffness {0} N·m/rad must be a finite number above 0")]
    Stiffness(f64),
    /// The gyro damping is not a positive finite number.
    #[error("gyro damping: {0} N·m·s/rad must be a finite number above 0")]
    Damping(f64),
}

/// A bridge's joint order against the model's: poses in, offsets out.
#[derive(Debug, Clone)]
struct ModelOrder {
    /// Bridge index of each model dof (`None`: not driven, taken at 0 rad).
    bridge_index: Vec<Option<usize>>,
    /// Scratch joint vector in model order.
    q_model: Vec<f64>,
}

impl ModelOrder {
    fn new(model: &BipedModel, joints: &[JointSpec]) -> Self {
        let bridge_index: Vec<Option<usize>> = model
            .robot()
            .dof_names()
            .map(|n| joints.iter().position(|j| j.name == n))
            .collect();
        let q_model = vec![0.0; bridge_index.len()];
        Self {
            bridge_index,
            q_model,
        }
    }

    /// The pose `positions_rad` (bridge order) in model order.
    fn pose(&mut self, positions_rad: &[f64]) -> &[f64] {
        for (q, b) in self.q_model.iter_mut().zip(&self.bridge_index) {
            *q = b.map_or(0.0, |b| positions_rad[b]);
        }
        &self.q_model
    }

    /// Adds `offsets` (model order) to `out` (bridge order).
    fn add(&self, offsets: &[f64], out: &mut [f64]) {
        for (o, b) in offsets.iter().zip(&self.bridge_index) {
            if let Some(b) = b {
                out[*b] += o;
            }
        }
    }
}

/// The compensation of one robot for one bridge's joint order.
#[derive(Debug, Clone)]
pub struct SagCompensation {
    model: BipedModel,
    kp_nm_per_rad: f64,
    order: ModelOrder,
}

impl SagCompensation {
    /// Compensation for servos of stiffness `kp_nm_per_rad` on `model`, for a bridge driving
    /// `joints`. Movable joints of the model the bridge does not drive (a board with servos
    /// on the legs only) are taken at 0 rad.
    pub fn new(
        model: BipedModel,
        kp_nm_per_rad: f64,
        joints: &[JointSpec],
    ) -> Result<Self, CompensationError> {
        if !(kp_nm_per_rad.is_finite() && kp_nm_per_rad > 0.0) {
            return Err(CompensationError::Stiffness(kp_nm_per_rad));
        }
        let order = ModelOrder::new(&model, joints);
        Ok(Self {
            model,
            kp_nm_per_rad,
            order,
        })
    }

    /// The servo stiffness (N·m/rad).
    pub fn kp_nm_per_rad(&self) -> f64 {
        self.kp_nm_per_rad
    }

    /// Adds the compensation of the pose `positions_rad` (bridge order) to `out` (bridge
    /// order). On a pose the model cannot evaluate (never for finite positions) `out` is
    /// left as it is and the reason returned.
    pub fn add_to(&mut self, positions_rad: &[f64], out: &mut [f64]) -> Result<(), String> {
        let q = self.order.pose(positions_rad);
        let offsets = self
            .model
            .sag_compensation_rad(q, self.kp_nm_per_rad)
            .map_err(|e| e.to_string())?;
        self.order.add(&offsets, out);
        Ok(())
    }
}

/// How old the newest body rate may be for [`GyroDamping`] to use it (s): five periods of a
/// 100 Hz IMU. Older, the damping is off until a fresh one comes.
pub const GYRO_MAX_AGE_S: f64 = 0.05;

/// Gyro damping in the command path: the legs on the floor damp the body's rotation, read
/// by a gyroscope on the base, as servos with `damping_nm_s_per_rad` more derivative gain
/// would ([`ik_solver::BipedModel::gyro_damping_rad`]): each joint of those legs aims
/// `damping / kp · (axis · ω)` further. Position servos damp only their own speed, so a
/// robot stopped on compliant servos rocks on its stance foot for seconds; a bus servo's D
/// gain is the hardware knob, this the one for any servo with a gyro on the body.
#[derive(Debug, Clone)]
pub struct GyroDamping {
    model: BipedModel,
    gain_s: f64,
    order: ModelOrder,
    /// The newest body rate (rad/s, base frame) and when it was measured (the bridge's
    /// time, s).
    rate: Option<(f64, nalgebra::Vector3<f64>)>,
}

impl GyroDamping {
    /// Damping of `damping_nm_s_per_rad` for servos of stiffness `kp_nm_per_rad` on
    /// `model`, for a bridge driving `joints`.
    pub fn new(
        model: BipedModel,
        damping_nm_s_per_rad: f64,
        kp_nm_per_rad: f64,
        joints: &[JointSpec],
    ) -> Result<Self, CompensationError> {
        if !(kp_nm_per_rad.is_finite() && kp_nm_per_rad > 0.0) {
            return Err(CompensationError::Stiffness(kp_nm_per_rad));
        }
        if !(damping_nm_s_per_rad.is_finite() && damping_nm_s_per_rad > 0.0) {
            return Err(CompensationError::Damping(damping_nm_s_per_rad));
        }
        let order = ModelOrder::new(&model, joints);
        Ok(Self {
            model,
            gain_s: damping_nm_s_per_rad / kp_nm_per_rad,
            order,
            rate: None,
        })
    }

    /// The offset per rad/s of body rate along a joint's axis (s).
    pub fn gain_s(&self) -> f64 {
        self.gain_s
    }

    /// The body's angular velocity `rate_rad_s` (base frame), measured at `t_s` (the
    /// bridge's time). A non-finite rate is not taken (the newest finite one stays, and
    /// ages).
    pub fn set_body_rate(&mut self, t_s: f64, rate_rad_s: nalgebra::Vector3<f64>) {
        if rate_rad_s.iter().all(|w| w.is_finite()) && t_s.is_finite() {
            self.rate = Some((t_s, rate_rad_s));
        }
    }

    /// Whether a body rate at most [`GYRO_MAX_AGE_S`] old at `t_s` is there to damp with.
    pub fn fresh(&self, t_s: f64) -> bool {
        self.rate
            .is_some_and(|(at, _)| t_s - at <= GYRO_MAX_AGE_S + 1e-9)
    }

    /// Adds the damping offsets of the pose `positions_rad` (bridge order) to `out` (bridge
    /// order), with the body rate as it is at `t_s`; nothing when it is not fresh
    /// ([`Self::fresh`]). Returns whether it added.
    pub fn add_to(
        &mut self,
        t_s: f64,
        positions_rad: &[f64],
        out: &mut [f64],
    ) -> Result<bool, String> {
        let Some((_, w)) = self.rate.filter(|_| self.fresh(t_s)) else {
            return Ok(false);
        };
        let q = self.order.pose(positions_rad);
        let offsets = self
            .model
            .gyro_damping_rad(q, &w, self.gain_s)
            .map_err(|e| e.to_string())?;
        self.order.add(&offsets, out);
        Ok(true)
    }
}
