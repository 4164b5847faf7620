//! The simulator's settings: servo model, physics step, floor, fall detection.
//!
//! ```yaml
//! kp_nm_per_rad: 30.0        # servo stiffness
//! kv_nm_s_per_rad: 0.25      # servo damping
//! torque_limit_nm: null      # null = each joint's URDF effort
//! ```

use serde::{Deserialize, Serialize};

use crate::error::SimError;

/// Settings of a [`crate::Sim`]. Defaults are the values the MuJoCo prototype walked with.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimConfig {
    /// Position-servo stiffness: torque per radian of error (N·m/rad). Also the `kp` of the
    /// sag compensation (target = plan + static torque / kp).
    pub kp_nm_per_rad: f64,
    /// Position-servo damping: torque per rad/s of joint speed (N·m·s/rad).
    pub kv_nm_s_per_rad: f64,
    /// Servo torque limit (N·m) for every joint; `None` = each joint's URDF `effort`.
    pub torque_limit_nm: Option<f64>,
    /// Reflected rotor inertia added to every joint (kg·m²): a geared servo's motor seen
    /// through its gearbox. Keeps the light limbs stable at a 1 ms step.
    pub armature_kg_m2: f64,
    /// Physics step (s).
    pub timestep_s: f64,
    /// Sliding friction coefficient of soles and floor.
    pub friction: f64,
    /// The robot has fallen when its base tilts more than this from upright (deg).
    pub fall_tilt_deg: f64,
    /// The robot has fallen when its base drops more than this below its height at the last
    /// [`crate::Sim::reset`] or [`crate::Sim::stand`] (m).
    pub fall_height_drop_m: f64,
    /// How long the servos hold the first pose before a plan is played or a backend reports
    /// ready (s): the robot settles on its feet.
    pub settle_s: f64,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            kp_nm_per_rad: 30.0,
            kv_nm_s_per_rad: 0.25,
            torque_limit_nm: None,
            armature_kg_m2: 0.005,
            timestep_s: 0.001,
            friction: 1.0,
            fall_tilt_deg: 30.0,
            fall_height_drop_m: 0.1,
            settle_s: 1.0,
        }
    }
}

fn check(key: &'static str, value: f64, lo: f64, hi: f64, unit: &str) -> Result<(), SimError> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(SimError::Config {
            key,
            value,
            why: format!("must be within [{lo}, {hi}] {unit}"),
        })
    }
}

fn positive(key: &'static str, value: f64, hi: f64, unit: &str) -> Result<(), SimError> {
    check(key, value, 0.0, hi, unit)?;
    if value > 0.0 {
        Ok(())
    } else {
        Err(SimError::Config {
            key,
            value,
            why: format!("must be above 0 {unit}"),
        })
    }
}

impl SimConfig {
    /// Parses the YAML text (a flat mapping of the keys above; unknown keys are refused by
    /// name) and validates it.
    ///
    /// ```
    /// let cfg = sim_bridge::SimConfig::from_yaml_str("kp_nm_per_rad: 20.0").unwrap();
    /// assert_eq!(cfg.kp_nm_per_rad, 20.0);
    /// assert!(sim_bridge::SimConfig::from_yaml_str("kp: 20.0").is_err());
    /// ```
    pub fn from_yaml_str(text: &str) -> Result<Self, SimError> {
        let cfg: Self =
            serde_norway::from_str(text).map_err(|e| SimError::ConfigParse(e.to_string()))?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Checks every value against its bounds; the error names the key.
    pub fn validate(&self) -> Result<(), SimError> {
        positive("kp_nm_per_rad", self.kp_nm_per_rad, 1e4, "N·m/rad")?;
        check(
            "kv_nm_s_per_rad",
            self.kv_nm_s_per_rad,
            0.0,
            1e3,
            "N·m·s/rad",
        )?;
        if let Some(t) = self.torque_limit_nm {
            positive("torque_limit_nm", t, 1e4, "N·m")?;
        }
        check("armature_kg_m2", self.armature_kg_m2, 0.0, 10.0, "kg·m²")?;
        positive("timestep_s", self.timestep_s, 0.01, "s")?;
        if self.timestep_s < 1e-5 {
            return Err(SimError::Config {
                key: "timestep_s",
                value: self.timestep_s,
                why: "must be at least 1e-5 s".into(),
            });
        }
        positive("friction", self.friction, 10.0, "")?;
        positive("fall_tilt_deg", self.fall_tilt_deg, 90.0, "deg")?;
        positive("fall_height_drop_m", self.fall_height_drop_m, 100.0, "m")?;
        check("settle_s", self.settle_s, 0.0, 600.0, "s")?;
        Ok(())
    }
}
