//! Servo-sag compensation in the command path: position servos are springs
//! (ALGORITHM.md), so under the robot's weight a joint settles torque / kp short of its
//! target. The bridge aims each servo the static torque of the commanded pose / kp further
//! ([`ik_solver::BipedModel::sag_compensation_rad`]: URDF mass model, level base, stance read
//! from the feet's heights), then applies the URDF limits to the result.

use ik_solver::BipedModel;

use crate::limits::JointSpec;

/// Why compensation cannot be set up for a bridge.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CompensationError {
    /// The stiffness is not a positive finite number.
    #[error("sag compensation: servo stiffness {0} N·m/rad must be a finite number above 0")]
    Stiffness(f64),
}

/// The compensation of one robot for one bridge's joint order.
#[derive(Debug, Clone)]
pub struct SagCompensation {
    model: BipedModel,
    kp_nm_per_rad: f64,
    /// Bridge index of each model dof (`None`: not driven, taken at 0 rad).
    bridge_index: Vec<Option<usize>>,
    /// Scratch joint vector in model order.
    q_model: Vec<f64>,
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
        let bridge_index: Vec<Option<usize>> = model
            .robot()
            .dof_names()
            .map(|n| joints.iter().position(|j| j.name == n))
            .collect();
        let q_model = vec![0.0; bridge_index.len()];
        Ok(Self {
            model,
            kp_nm_per_rad,
            bridge_index,
            q_model,
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
        for (q, b) in self.q_model.iter_mut().zip(&self.bridge_index) {
            *q = b.map_or(0.0, |b| positions_rad[b]);
        }
        let offsets = self
            .model
            .sag_compensation_rad(&self.q_model, self.kp_nm_per_rad)
            .map_err(|e| e.to_string())?;
        for (o, b) in offsets.iter().zip(&self.bridge_index) {
            if let Some(b) = b {
                out[*b] += o;
            }
        }
        Ok(())
    }
}
