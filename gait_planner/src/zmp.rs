//! The cart-table model (Kajita et al., 2003): the robot as a point mass at its whole-body
//! CoM above a flat floor. Its zero-moment point (ZMP) is where the floor's reaction must
//! act for the mass to accelerate as planned without tipping:
//!
//! ```text
//! zmp_xy = com_xy - com_z * accel_xy / (g + accel_z)
//! ```
//!
//! At rest the ZMP is the CoM's floor point; accelerating moves it backwards, decelerating
//! forwards (of the motion). The physical centre of pressure of the contact forces (what
//! `sim_bridge` measures) is the real ZMP: it must stay inside the support polygon, or a
//! sole edge becomes an axis the robot tips about. Angular momentum (the swinging leg's) is
//! left out, as in the model.

use ik_solver::support::Xy;
use nalgebra::{Point3, Vector3};

/// Standard gravity (m/s²).
pub const GRAVITY_M_S2: f64 = 9.80665;

/// The ZMP of a point mass at `com_m` (floor at z = 0) with acceleration `accel_m_s2`.
///
/// ```
/// use gait_planner::zmp::{GRAVITY_M_S2, cart_table_zmp};
/// use nalgebra::{Point3, Vector3};
/// // 0.2 m up, accelerating forward at g / 10: the ZMP is 0.02 m behind the CoM.
/// let z = cart_table_zmp(Point3::new(0.1, 0.0, 0.2), Vector3::new(GRAVITY_M_S2 / 10.0, 0.0, 0.0));
/// assert!((z[0] - 0.08).abs() < 1e-12 && z[1] == 0.0);
/// ```
pub fn cart_table_zmp(com_m: Point3<f64>, accel_m_s2: Vector3<f64>) -> Xy {
    let k = com_m.z / (GRAVITY_M_S2 + accel_m_s2.z);
    [com_m.x - k * accel_m_s2.x, com_m.y - k * accel_m_s2.y]
}
