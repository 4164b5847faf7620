//! The DDS context from the standard ROS environment variables (`ROS_DOMAIN_ID`,
//! `ROS_AUTOMATIC_DISCOVERY_RANGE`, `ROS_STATIC_PEERS`, `ROS_LOCALHOST_ONLY`;
//! `ROS_SECURITY_ENABLE=true` is refused: no DDS Security here).

use std::net::{IpAddr, Ipv4Addr, ToSocketAddrs};

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
    /// No discovery at all: no multicast, no announcements, and every other participant
    /// refused, even on this machine and even if it contacts this one (`ROS_STATIC_PEERS`
    /// are not used either), as rmw_fastrtps does in ROS 2 Jazzy.
    Off,
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
        "LOCALHOST" => DiscoveryRange::Localhost,
        "OFF" => DiscoveryRange::Off,
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

/// The hosts of `ROS_STATIC_PEERS`: addresses or host names separated by `;` (empty
/// entries skipped), each resolved to its first address. A host that does not resolve is
/// an error naming it.
pub fn static_peers_from(var: impl Fn(&str) -> Option<String>) -> Result<Vec<IpAddr>, RosError> {
    let Some(list) = var("ROS_STATIC_PEERS") else {
        return Ok(Vec::new());
    };
    list.split(';')
        .map(str::trim)
        .filter(|p| !p.is_empty())
        .map(|peer| {
            if let Ok(ip) = peer.parse::<IpAddr>() {
                return Ok(ip);
            }
            (peer, 0)
                .to_socket_addrs()
                .ok()
                .and_then(|mut a| a.next())
                .map(|a| a.ip())
                .ok_or_else(|| RosError::Env {
                    name: "ROS_STATIC_PEERS",
                    value: list.clone(),
                    why: format!("`{peer}` is neither an IP address nor a host name that resolves"),
                })
        })
        .collect()
}

/// Which thread puts a node's messages on the wire.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SendThread {
    /// The publishing thread itself, during `publish`: one thread hand-off less per message
    /// (the lowest latency), the default.
    Publishing,
    /// The DDS participant's own thread, woken for each message: for composed nodes on one
    /// executor thread, which is the process's bottleneck, while the DDS thread sends on the
    /// other core (BENCHMARKS.md, "A writer that sends its own DATA").
    Dds,
}

/// A DDS context for the environment's domain, discovery range and static peers. With
/// LOCALHOST, DDS traffic stays on 127.0.0.1.
pub fn context_from_env() -> Result<Context, RosError> {
    context_from_env_sending_on(SendThread::Publishing)
}

/// [`context_from_env`], with messages sent on the given thread.
pub fn context_from_env_sending_on(send: SendThread) -> Result<Context, RosError> {
    let (domain, range) = ros_environment()?;
    context_with_peers(domain, range, &static_peers_for(range)?, send)
}

/// A DDS context for a domain and discovery range, with the static peers of the
/// environment's `ROS_STATIC_PEERS` (not read with OFF, which uses none). With LOCALHOST,
/// DDS traffic stays on 127.0.0.1.
pub fn context_for(domain: u16, range: DiscoveryRange) -> Result<Context, RosError> {
    context_with_peers(
        domain,
        range,
        &static_peers_for(range)?,
        SendThread::Publishing,
    )
}

fn static_peers_for(range: DiscoveryRange) -> Result<Vec<IpAddr>, RosError> {
    match range {
        DiscoveryRange::Off => Ok(Vec::new()),
        DiscoveryRange::Localhost | DiscoveryRange::Subnet => {
            static_peers_from(|name| std::env::var(name).ok())
        }
    }
}

/// A DDS context for a domain, a discovery range and static peers, as ROS 2 Jazzy's
/// rmw_fastrtps reads `ROS_AUTOMATIC_DISCOVERY_RANGE` and `ROS_STATIC_PEERS`: SUBNET finds
/// participants by multicast on the local networks; LOCALHOST keeps DDS traffic on
/// 127.0.0.1; both also announce themselves by unicast to the static peers (with
/// LOCALHOST, only peers on this machine can answer). OFF discovers nothing: no multicast,
/// no announcements, other participants refused, static peers unused. `send`: which thread
/// sends a message.
pub fn context_with_peers(
    domain: u16,
    range: DiscoveryRange,
    static_peers: &[IpAddr],
    send: SendThread,
) -> Result<Context, RosError> {
    let dds = |what: &str, e: &dyn std::fmt::Display| RosError::Dds {
        what: what.into(),
        message: e.to_string(),
    };
    let builder = ros2_client::dds::rustdds::DomainParticipantBuilder::new(domain)
        .send_from_writing_thread(send == SendThread::Publishing);
    let builder = match range {
        DiscoveryRange::Localhost => builder
            .with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)])
            .with_static_peers(static_peers.iter().copied()),
        DiscoveryRange::Subnet => builder.with_static_peers(static_peers.iter().copied()),
        DiscoveryRange::Off => builder
            .multicast(false)
            .same_host_loopback(false)
            .remote_participants(false),
    };
    let participant = builder.build().map_err(|e| dds("DDS participant", &e))?;
    Context::from_domain_participant(participant).map_err(|e| dds("ROS context", &e))
}
