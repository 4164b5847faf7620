//! The DDS context from the standard ROS environment variables (`ROS_DOMAIN_ID`,
//! `ROS_AUTOMATIC_DISCOVERY_RANGE`, `ROS_LOCALHOST_ONLY`; `ROS_SECURITY_ENABLE=true` is
//! refused: no DDS Security here).

use std::net::{IpAddr, Ipv4Addr};

use ros2_client::Context;

use crate::error::RosError;

/// The DDS discovery range of `ROS_AUTOMATIC_DISCOVERY_RANGE` (and the older
/// `ROS_LOCALHOST_ONLY=1`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DiscoveryRange {
    /// Only this machine (127.0.0.1).
    Localhost,
    /// The default: the local networks.
    Subnet,
}

/// Reads `ROS_DOMAIN_ID` (0–232, default 0) and the discovery range from the environment.
pub fn ros_environment() -> Result<(u16, DiscoveryRange), RosError> {
    ros_environment_from(|name| std::env::var(name).ok())
}

/// [`ros_environment`] over any variable lookup (for tests and embedding).
pub fn ros_environment_from(
    var: impl Fn(&str) -> Option<String>,
) -> Result<(u16, DiscoveryRange), RosError> {
    let domain = match var("ROS_DOMAIN_ID") {
        Some(v) if !v.trim().is_empty() => {
            let id: u16 = v.trim().parse().map_err(|_| RosError::Env {
                name: "ROS_DOMAIN_ID",
                value: v.clone(),
                why: "not a number".into(),
            })?;
            if id > 232 {
                return Err(RosError::Env {
                    name: "ROS_DOMAIN_ID",
                    value: v,
                    why: "must be within 0..=232".into(),
                });
            }
            id
        }
        _ => 0,
    };
    // SROS2: a node that cannot do DDS Security must not join a secured graph silently
    // unsecured (its peers would never match it, or it would leak what they protect).
    if let Some(v) = var("ROS_SECURITY_ENABLE")
        && v.trim().eq_ignore_ascii_case("true")
    {
        return Err(RosError::Env {
            name: "ROS_SECURITY_ENABLE",
            value: v,
            why: "ROS 2 security (SROS2) is not supported: these nodes use RustDDS without DDS Security; unset it to run them unsecured".into(),
        });
    }
    let range = match var("ROS_AUTOMATIC_DISCOVERY_RANGE")
        .unwrap_or_default()
        .to_ascii_uppercase()
        .as_str()
    {
        "LOCALHOST" | "OFF" => DiscoveryRange::Localhost,
        "" | "SYSTEM_DEFAULT" | "SUBNET" => {
            if var("ROS_LOCALHOST_ONLY").as_deref() == Some("1") {
                DiscoveryRange::Localhost
            } else {
                DiscoveryRange::Subnet
            }
        }
        other => {
            return Err(RosError::Env {
                name: "ROS_AUTOMATIC_DISCOVERY_RANGE",
                value: other.to_owned(),
                why: "expected LOCALHOST, SUBNET, OFF or SYSTEM_DEFAULT".into(),
            });
        }
    };
    Ok((domain, range))
}

/// A DDS context for the environment's domain and discovery range. With LOCALHOST, DDS
/// traffic stays on 127.0.0.1.
pub fn context_from_env() -> Result<Context, RosError> {
    let (domain, range) = ros_environment()?;
    context_for(domain, range)
}

/// A DDS context for a domain and discovery range. With LOCALHOST, DDS traffic stays on
/// 127.0.0.1.
pub fn context_for(domain: u16, range: DiscoveryRange) -> Result<Context, RosError> {
    let dds = |what: &str, e: &dyn std::fmt::Display| RosError::Dds {
        what: what.into(),
        message: e.to_string(),
    };
    match range {
        DiscoveryRange::Localhost => {
            let participant = ros2_client::dds::rustdds::DomainParticipantBuilder::new(domain)
                .with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)])
                .build()
                .map_err(|e| dds("DDS participant", &e))?;
            Context::from_domain_participant(participant).map_err(|e| dds("ROS context", &e))
        }
        DiscoveryRange::Subnet => {
            Context::with_options(ros2_client::ContextOptions::new().domain_id(domain))
                .map_err(|e| dds("ROS context", &e))
        }
    }
}
