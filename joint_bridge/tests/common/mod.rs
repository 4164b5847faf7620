//! What the joint bridge's tests share.
#![allow(dead_code)]

use joint_bridge::JointSpec;

/// A hand-made joint.
pub fn spec(name: &str, lower: f64, upper: f64, velocity: f64) -> JointSpec {
    JointSpec {
        name: name.into(),
        lower_rad: lower,
        upper_rad: upper,
        velocity_rad_s: velocity,
    }
}

/// Joint names as a command carries them.
pub fn names(n: &[&str]) -> Vec<String> {
    n.iter().map(|s| s.to_string()).collect()
}
