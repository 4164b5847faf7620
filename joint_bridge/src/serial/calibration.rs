//! Per-joint calibration of a servo board: which servo drives each joint and how radians
//! map to the servo's units.
//!
//! File format (YAML, unknown keys refused):
//!
//! ```yaml
//! protocol: dynamixel2          # the board's protocol; must match the backend's
//! joints:
//!   l_knee: { id: 3, zero: 2048, direction: -1, units_per_rad: 651.8986, min: 1100, max: 2100 }
//! ```
//!
//! | key | meaning |
//! |---|---|
//! | `id` | Dynamixel bus id, or Maestro / SSC-32U channel |
//! | `zero` | servo units at joint angle 0 (ticks, or µs of pulse) |
//! | `direction` | `1` if the servo's units grow with the URDF angle, `-1` if they shrink |
//! | `units_per_rad` | ticks (Dynamixel) or µs (Maestro, SSC-32U) per radian, > 0 |
//! | `min`, `max` | the servo units the joint may be sent to (mechanical stops), `min` < `max` |
//! | `speed`, `acceleration` | Maestro only, optional top-level keys: the board's own speed and acceleration limits for every channel (0 = none) |
//!
//! units = `zero + direction × units_per_rad × angle_rad`, clamped into [`min`, `max`].

use std::collections::BTreeMap;
use std::path::Path;

use serde::Deserialize;

use super::Protocol;

/// A calibration file that cannot be used, naming the file, joint and key.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CalibrationError {
    /// The file cannot be read.
    #[error("calibration file {path}: cannot read: {why}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        why: String,
    },
    /// Not valid YAML of this format.
    #[error("calibration {source_name}: {why}")]
    Parse {
        /// The file or source.
        source_name: String,
        /// Why.
        why: String,
    },
    /// A bad value.
    #[error("calibration {source_name}: joint `{joint}`, key `{key}`: {why}")]
    Invalid {
        /// The file or source.
        source_name: String,
        /// The joint (or `-` for top-level keys).
        joint: String,
        /// The key.
        key: &'static str,
        /// What is wrong.
        why: String,
    },
}

/// One joint's servo.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointCalibration {
    /// Bus id or channel.
    pub id: u8,
    /// Units at angle 0.
    pub zero: f64,
    /// `1` or `-1`.
    pub direction: i8,
    /// Units per radian.
    pub units_per_rad: f64,
    /// Lowest units allowed.
    pub min: f64,
    /// Highest units allowed.
    pub max: f64,
    /// Boards that cannot measure (Maestro, SSC-32U): the units sent first when the board
    /// outputs no pulse yet (the robot's rest pose); default `zero`.
    #[serde(default)]
    pub rest: Option<f64>,
}

impl JointCalibration {
    /// The units of the rest pose: `rest`, else `zero`.
    pub fn rest_units(&self) -> f64 {
        self.rest.unwrap_or(self.zero)
    }

    /// Servo units for an angle, clamped into [`min`, `max`]. A non-finite angle gives
    /// `None`: it is never sent.
    pub fn to_units(&self, angle_rad: f64) -> Option<f64> {
        let u = self.zero + f64::from(self.direction) * self.units_per_rad * angle_rad;
        u.is_finite().then(|| u.clamp(self.min, self.max))
    }

    /// The angle for servo units.
    pub fn to_rad(&self, units: f64) -> f64 {
        (units - self.zero) / (f64::from(self.direction) * self.units_per_rad)
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    protocol: String,
    #[serde(default)]
    speed: Option<u16>,
    #[serde(default)]
    acceleration: Option<u16>,
    #[serde(default)]
    start_speed: Option<u16>,
    joints: BTreeMap<String, JointCalibration>,
}

/// SSC-32U: the default speed of the first move to the rest pose (µs/s; about 0.5 rad/s
/// for a servo of 636.6 µs/rad).
pub const DEFAULT_START_SPEED_US_S: u16 = 300;

/// A board's calibration: one entry per joint it drives.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// The board's protocol.
    pub protocol: Protocol,
    /// Maestro speed limit for every channel (0.25 µs / 10 ms; 0 = none).
    pub speed: u16,
    /// Maestro acceleration limit for every channel (0 = none).
    pub acceleration: u16,
    /// SSC-32U: speed of the first move to the rest pose (µs per second), kept on every
    /// move until the board outputs the commanded pulses.
    pub start_speed_us_s: u16,
    /// By joint name.
    pub joints: BTreeMap<String, JointCalibration>,
}

impl Calibration {
    /// Reads and validates a calibration file.
    pub fn from_file(path: &Path) -> Result<Self, CalibrationError> {
        let text = std::fs::read_to_string(path).map_err(|e| CalibrationError::Read {
            path: path.display().to_string(),
            why: e.to_string(),
        })?;
        Self::from_yaml_str(&text, &path.display().to_string())
    }

    /// Parses and validates calibration YAML; `source_name` names it in errors.
    ///
    /// ```
    /// use joint_bridge::serial::Calibration;
    /// let c = Calibration::from_yaml_str(
    ///     "protocol: ssc32\njoints:\n  l_knee: { id: 2, zero: 1500, direction: -1, units_per_rad: 636.62, min: 900, max: 2100 }\n",
    ///     "example",
    /// ).unwrap();
    /// // 0.5 rad of knee: 1500 - 318.31 µs.
    /// assert!((c.joints["l_knee"].to_units(0.5).unwrap() - 1181.69).abs() < 1e-9);
    /// let bad = Calibration::from_yaml_str(
    ///     "protocol: ssc32\njoints:\n  l_knee: { id: 2, zero: 1500, direction: 0, units_per_rad: 636.62, min: 900, max: 2100 }\n",
    ///     "example",
    /// ).unwrap_err();
    /// assert!(bad.to_string().contains("joint `l_knee`, key `direction`"));
    /// ```
    pub fn from_yaml_str(text: &str, source_name: &str) -> Result<Self, CalibrationError> {
        let file: File = serde_norway::from_str(text).map_err(|e| CalibrationError::Parse {
            source_name: source_name.to_string(),
            why: e.to_string(),
        })?;
        let invalid = |joint: &str, key: &'static str, why: String| CalibrationError::Invalid {
            source_name: source_name.to_string(),
            joint: joint.to_string(),
            key,
            why,
        };
        let protocol: Protocol = file
            .protocol
            .parse()
            .map_err(|e: String| invalid("-", "protocol", e))?;
        if protocol != Protocol::Maestro {
            if file.speed.is_some() {
                return Err(invalid(
                    "-",
                    "speed",
                    format!("only for maestro, not {protocol}"),
                ));
            }
            if file.acceleration.is_some() {
                return Err(invalid(
                    "-",
                    "acceleration",
                    format!("only for maestro, not {protocol}"),
                ));
            }
        }
        if protocol != Protocol::Ssc32 && file.start_speed.is_some() {
            return Err(invalid(
                "-",
                "start_speed",
                format!("only for ssc32, not {protocol}"),
            ));
        }
        if file.start_speed == Some(0) {
            return Err(invalid(
                "-",
                "start_speed",
                "0 µs/s would never reach the rest pose".into(),
            ));
        }
        for (key, v) in [("speed", file.speed), ("acceleration", file.acceleration)] {
            if let Some(v) = v
                && v > super::maestro::MAX_VALUE
            {
                return Err(invalid("-", key, format!("{v} is above 16383")));
            }
        }
        if file.joints.is_empty() {
            return Err(invalid("-", "joints", "no joint is calibrated".into()));
        }
        let (id_lo, id_hi) = protocol.id_range();
        let (u_lo, u_hi) = protocol.unit_range();
        let unit = protocol.unit_name();
        let mut ids: BTreeMap<u8, &str> = BTreeMap::new();
        for (name, j) in &file.joints {
            if !(id_lo..=id_hi).contains(&j.id) {
                return Err(invalid(
                    name,
                    "id",
                    format!("{} is outside {id_lo}..={id_hi} for {protocol}", j.id),
                ));
            }
            if let Some(other) = ids.insert(j.id, name) {
                return Err(invalid(
                    name,
                    "id",
                    format!("{} is also the id of joint `{other}`", j.id),
                ));
            }
            if j.direction != 1 && j.direction != -1 {
                return Err(invalid(
                    name,
                    "direction",
                    format!("{} is neither 1 nor -1", j.direction),
                ));
            }
            if !(j.units_per_rad.is_finite() && j.units_per_rad > 0.0) {
                return Err(invalid(
                    name,
                    "units_per_rad",
                    format!(
                        "{} is not a positive number of {unit} per radian",
                        j.units_per_rad
                    ),
                ));
            }
            for (key, v) in [("min", j.min), ("max", j.max), ("zero", j.zero)] {
                if !(v.is_finite() && (u_lo..=u_hi).contains(&v)) {
                    return Err(invalid(
                        name,
                        key,
                        format!("{v} {unit} is outside what {protocol} can send ({u_lo}..={u_hi})"),
                    ));
                }
            }
            if j.min >= j.max {
                return Err(invalid(
                    name,
                    "max",
                    format!("{} is not above min {}", j.max, j.min),
                ));
            }
            if let Some(rest) = j.rest {
                if protocol.measures() {
                    return Err(invalid(
                        name,
                        "rest",
                        format!(
                            "only for boards that cannot measure (maestro, ssc32); {protocol} starts from the measured pose"
                        ),
                    ));
                }
                if !(rest.is_finite() && (j.min..=j.max).contains(&rest)) {
                    return Err(invalid(
                        name,
                        "rest",
                        format!("{rest} is outside [min, max] = [{}, {}]", j.min, j.max),
                    ));
                }
            }
            if !(j.min..=j.max).contains(&j.zero) {
                return Err(invalid(
                    name,
                    "zero",
                    format!("{} is outside [min, max] = [{}, {}]", j.zero, j.min, j.max),
                ));
            }
        }
        Ok(Self {
            protocol,
            speed: file.speed.unwrap_or(0),
            acceleration: file.acceleration.unwrap_or(0),
            start_speed_us_s: file.start_speed.unwrap_or(DEFAULT_START_SPEED_US_S),
            joints: file.joints,
        })
    }
}
