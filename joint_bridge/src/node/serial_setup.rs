//! The `serial` backend of the joint_bridge node: its parameters, checked, and the backend
//! built from them (the calibration decides which joints are driven).

use std::collections::BTreeMap;

use crate::serial::{Calibration, Protocol, SerialBackend, SerialConfig};
use crate::{Backoff, JointSpec};
use node_runtime::NodeSetup;
use ros2_client::ParameterValue;

/// The serial parameter names.
pub const PARAMS: [&str; 7] = [
    "protocol",
    "port",
    "baud",
    "calibration_file",
    "reply_timeout_s",
    "retry_first_s",
    "retry_max_s",
];

/// The serial settings, checked.
pub struct SerialParams {
    pub protocol: String,
    pub port: String,
    pub baud: u32,
    pub calibration_file: String,
    pub reply_timeout_s: f64,
    pub retry_first_s: f64,
    pub retry_max_s: f64,
}

/// `v` if within [lo, hi], else an error naming the parameter.
pub fn in_range(name: &str, v: f64, lo: f64, hi: f64, unit: &str) -> anyhow::Result<f64> {
    if (lo..=hi).contains(&v) {
        Ok(v)
    } else {
        anyhow::bail!("parameter `{name}` = {v} is out of range [{lo}, {hi}] {unit}")
    }
}

impl SerialParams {
    /// Reads and checks the serial parameters.
    pub fn from_setup(setup: &NodeSetup) -> anyhow::Result<Self> {
        let b = in_range(
            "baud",
            setup.f64_param("baud", 1_000_000.0)?,
            300.0,
            12e6,
            "baud",
        )?;
        if b.fract() != 0.0 {
            anyhow::bail!("parameter `baud` = {b} is not a whole number");
        }
        Ok(Self {
            protocol: setup.str_param("protocol", "dynamixel2")?,
            port: setup.str_param("port", "/dev/ttyUSB0")?,
            baud: b as u32,
            calibration_file: setup.str_param("calibration_file", "")?,
            reply_timeout_s: in_range(
                "reply_timeout_s",
                setup.f64_param("reply_timeout_s", 0.01)?,
                1e-4,
                1.0,
                "s",
            )?,
            retry_first_s: in_range(
                "retry_first_s",
                setup.f64_param("retry_first_s", 0.5)?,
                0.01,
                60.0,
                "s",
            )?,
            retry_max_s: in_range(
                "retry_max_s",
                setup.f64_param("retry_max_s", 5.0)?,
                0.01,
                600.0,
                "s",
            )?,
        })
    }

    /// True when the protocol reads positions back.
    pub fn measures(&self) -> bool {
        self.protocol
            .parse::<Protocol>()
            .is_ok_and(Protocol::measures)
    }

    /// "dynamixel2 on /dev/ttyUSB0 at 1000000 baud".
    pub fn describe(&self) -> String {
        format!("{} on {} at {} baud", self.protocol, self.port, self.baud)
    }

    /// The declared parameter values.
    pub fn declared(&self) -> BTreeMap<String, ParameterValue> {
        BTreeMap::from([
            (
                "protocol".to_string(),
                ParameterValue::String(self.protocol.clone()),
            ),
            (
                "port".to_string(),
                ParameterValue::String(self.port.clone()),
            ),
            (
                "baud".to_string(),
                ParameterValue::Integer(i64::from(self.baud)),
            ),
            (
                "calibration_file".to_string(),
                ParameterValue::String(self.calibration_file.clone()),
            ),
            (
                "reply_timeout_s".to_string(),
                ParameterValue::Double(self.reply_timeout_s),
            ),
            (
                "retry_first_s".to_string(),
                ParameterValue::Double(self.retry_first_s),
            ),
            (
                "retry_max_s".to_string(),
                ParameterValue::Double(self.retry_max_s),
            ),
        ])
    }

    /// The backend and its reconnection backoff; keeps in `joints` only the calibrated
    /// joints and returns the others' names (no servo on this board).
    pub fn backend(
        &self,
        robot_name: &str,
        joints: &mut Vec<JointSpec>,
    ) -> anyhow::Result<(SerialBackend, Backoff, Vec<String>)> {
        let protocol: Protocol = self
            .protocol
            .parse()
            .map_err(|e: String| anyhow::anyhow!("parameter `protocol`: {e}"))?;
        if self.calibration_file.is_empty() {
            anyhow::bail!(
                "parameter `calibration_file` is empty: the serial backend needs the joints' calibration (see config/calibration_{protocol}.yaml)"
            );
        }
        let calibration = Calibration::from_file(std::path::Path::new(&self.calibration_file))?;
        if calibration.protocol != protocol {
            anyhow::bail!(
                "calibration_file `{}` is for protocol {}, but parameter `protocol` is {protocol}",
                self.calibration_file,
                calibration.protocol
            );
        }
        if let Some(unknown) = calibration
            .joints
            .keys()
            .find(|n| !joints.iter().any(|j| &j.name == *n))
        {
            anyhow::bail!(
                "calibration_file `{}`: joint `{unknown}` is not a movable joint of robot `{robot_name}`",
                self.calibration_file
            );
        }
        let not_driven = joints
            .iter()
            .filter(|j| !calibration.joints.contains_key(&j.name))
            .map(|j| j.name.clone())
            .collect();
        joints.retain(|j| calibration.joints.contains_key(&j.name));
        let backend = SerialBackend::new(SerialConfig {
            port: self.port.clone(),
            baud: self.baud,
            calibration,
            reply_timeout_s: self.reply_timeout_s,
        });
        Ok((
            backend,
            Backoff {
                first_s: self.retry_first_s,
                max_s: self.retry_max_s.max(self.retry_first_s),
            },
            not_driven,
        ))
    }
}
