//! The ROS 2 command line and parameter files, as `ros2 run` users write them.

use node_runtime::{NodeSetup, RosArgs, node_parameters, topic_name};
use serde_norway::Value;

fn args(s: &str) -> Vec<String> {
    s.split_whitespace().map(String::from).collect()
}

#[test]
fn remaps_namespace_name_params_and_files() {
    let (own, r) = RosArgs::parse(
        args("--ros-args -r __ns:=/robot1 -r __node:=planner -r cmd_vel:=/teleop/cmd_vel -p step_length_m:=0.03 -p first_foot:=right --params-file a.yaml --log-level debug"),
        "gait_planner",
    )
    .unwrap();
    assert!(own.is_empty());
    assert_eq!(r.namespace.as_deref(), Some("/robot1"));
    assert_eq!(r.node_name.as_deref(), Some("planner"));
    assert_eq!(
        r.remaps,
        vec![("cmd_vel".to_string(), "/teleop/cmd_vel".to_string())]
    );
    assert_eq!(
        r.params[0],
        ("step_length_m".to_string(), Value::from(0.03))
    );
    assert_eq!(
        r.params[1],
        ("first_foot".to_string(), Value::String("right".into()))
    );
    assert_eq!(r.params_files, vec!["a.yaml".to_string()]);
    assert_eq!(r.log_level.as_deref(), Some("debug"));
}

#[test]
fn node_targeted_arguments_apply_to_that_node_only() {
    let line = args(
        "--ros-args -p ik_solver:robot_description_file:=a.urdf -p gait_planner:control_rate_hz:=50.0 -r joint_bridge:joint_commands:=/x",
    );
    let (_, r) = RosArgs::parse(line.clone(), "gait_planner").unwrap();
    assert_eq!(
        r.params,
        vec![("control_rate_hz".to_string(), Value::from(50.0))]
    );
    assert!(r.remaps.is_empty());
    let (_, r) = RosArgs::parse(line, "joint_bridge").unwrap();
    assert!(r.params.is_empty());
    assert_eq!(
        r.remaps,
        vec![("joint_commands".to_string(), "/x".to_string())]
    );
}

#[test]
fn own_arguments_and_ros_args_blocks() {
    let (own, r) = RosArgs::parse(
        args("--verbose --ros-args -p a:=1 -- extra --ros-args -p b:=true"),
        "n",
    )
    .unwrap();
    assert_eq!(own, args("--verbose extra"));
    assert_eq!(
        r.params,
        vec![
            ("a".to_string(), Value::from(1)),
            ("b".to_string(), Value::Bool(true))
        ]
    );
    // A node refuses arguments outside --ros-args, naming them.
    let setup = NodeSetup::from_args(args("--verbose --ros-args -p a:=1"), "n").unwrap();
    let err = setup.only_ros_args().unwrap_err().to_string();
    assert!(
        err.contains("unexpected arguments [\"--verbose\"]"),
        "{err}"
    );
    NodeSetup::from_args(args("--ros-args -p a:=1"), "n")
        .unwrap()
        .only_ros_args()
        .unwrap();
}

#[test]
fn bad_arguments_are_named() {
    for (line, needle) in [
        ("--ros-args -p", "-p needs a value"),
        ("--ros-args -p novalue", "name:=value"),
        ("--ros-args -r :=x", "empty name"),
        ("--ros-args --frobnicate", "--frobnicate"),
        ("--ros-args -p a:=[1,", "a:=[1,"),
        (
            "--ros-args --enclave /biped/planner",
            "--enclave /biped/planner: ROS 2 security (SROS2 enclaves) is not supported",
        ),
        ("--ros-args -e /x", "-e /x: ROS 2 security"),
    ] {
        let e = RosArgs::parse(args(line), "n").unwrap_err().to_string();
        assert!(e.contains(needle), "{line}: {e}");
    }
}

#[test]
fn parameter_files_wildcard_node_namespace_and_overrides() {
    let dir = std::env::temp_dir().join(format!("biped-rosargs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("p.yaml");
    std::fs::write(
        &file,
        "/**:\n  ros__parameters:\n    use_sim_time: true\n    rate_hz: 50.0\n\
         joint_bridge:\n  ros__parameters:\n    rate_hz: 200.0\n    watchdog:\n      timeout_s: 0.5\n\
         /robot1/joint_bridge:\n  ros__parameters:\n    backend: serial\n\
         ik_solver:\n  ros__parameters:\n    rate_hz: 1.0\n",
    )
    .unwrap();
    let line = format!(
        "--ros-args --params-file {} -p rate_hz:=300.0",
        file.display()
    );
    let (_, r) = RosArgs::parse(args(&line), "joint_bridge").unwrap();
    let p = node_parameters(&r, "joint_bridge", "/").unwrap();
    assert_eq!(p["use_sim_time"], Value::Bool(true));
    assert_eq!(p["rate_hz"], Value::from(300.0), "-p overrides files");
    assert_eq!(
        p["watchdog.timeout_s"],
        Value::from(0.5),
        "nested names are dotted"
    );
    assert!(!p.contains_key("backend"), "another namespace's section");
    let p = node_parameters(&r, "joint_bridge", "/robot1").unwrap();
    assert_eq!(p["backend"], Value::String("serial".into()));
    let e = node_parameters(
        &RosArgs {
            params_files: vec!["/nonexistent.yaml".into()],
            ..RosArgs::default()
        },
        "n",
        "/",
    )
    .unwrap_err();
    assert!(e.to_string().contains("/nonexistent.yaml"));
}

#[test]
fn topic_names_resolve_in_the_namespace_after_remaps() {
    let (_, r) = RosArgs::parse(
        args("--ros-args -r cmd_vel:=teleop/cmd_vel -r /joint_states:=/robot/joint_states"),
        "n",
    )
    .unwrap();
    let name = |ns: &str, t: &str| topic_name(&r, ns, t).unwrap().to_string();
    assert_eq!(name("/", "gait/phase"), "/gait/phase");
    assert_eq!(name("/robot1", "gait/phase"), "/robot1/gait/phase");
    assert_eq!(name("/", "cmd_vel"), "/teleop/cmd_vel");
    assert_eq!(name("/robot1", "cmd_vel"), "/robot1/teleop/cmd_vel");
    assert_eq!(name("/", "joint_states"), "/robot/joint_states");
    assert_eq!(name("/", "/rosout"), "/rosout");
}

#[test]
fn node_setup_reads_typed_parameters() {
    let s = NodeSetup::from_args(
        args("--ros-args -p rate_hz:=50 -p backend:=mock -p bad:=[1]"),
        "joint_bridge",
    )
    .unwrap();
    assert_eq!(s.f64_param("rate_hz", 100.0).unwrap(), 50.0);
    assert_eq!(s.f64_param("missing", 7.0).unwrap(), 7.0);
    assert_eq!(s.str_param("backend", "x").unwrap(), "mock");
    assert!(
        s.str_param("rate_hz", "")
            .unwrap_err()
            .to_string()
            .contains("rate_hz")
    );
    assert!(
        s.f64_param("bad", 0.0)
            .unwrap_err()
            .to_string()
            .contains("bad")
    );
    assert!(
        node_runtime::check_known(&s.params, &["rate_hz", "backend"])
            .unwrap_err()
            .to_string()
            .contains("`bad`")
    );
}

#[test]
fn domain_id_and_discovery_range_from_the_environment() {
    use node_runtime::{DiscoveryRange, ros_environment_from};
    let env = |pairs: &'static [(&'static str, &'static str)]| {
        move |k: &str| {
            pairs
                .iter()
                .find(|(n, _)| *n == k)
                .map(|(_, v)| v.to_string())
        }
    };
    assert_eq!(
        ros_environment_from(env(&[])).unwrap(),
        (0, DiscoveryRange::Subnet)
    );
    assert_eq!(
        ros_environment_from(env(&[
            ("ROS_DOMAIN_ID", "42"),
            ("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        ]))
        .unwrap(),
        (42, DiscoveryRange::Localhost)
    );
    assert_eq!(
        ros_environment_from(env(&[("ROS_LOCALHOST_ONLY", "1")]))
            .unwrap()
            .1,
        DiscoveryRange::Localhost
    );
    assert_eq!(
        ros_environment_from(env(&[("ROS_SECURITY_ENABLE", "false")]))
            .unwrap()
            .0,
        0
    );
    assert_eq!(
        ros_environment_from(env(&[("ROS_AUTOMATIC_DISCOVERY_RANGE", "off")]))
            .unwrap()
            .1,
        DiscoveryRange::Off
    );
    for (pairs, needle) in [
        (&[("ROS_DOMAIN_ID", "233")][..], "233"),
        (&[("ROS_DOMAIN_ID", "abc")][..], "abc"),
        (&[("ROS_AUTOMATIC_DISCOVERY_RANGE", "GALAXY")][..], "GALAXY"),
        (
            &[("ROS_SECURITY_ENABLE", "true")][..],
            "ROS_SECURITY_ENABLE",
        ),
    ] {
        let owned: Vec<(String, String)> = pairs
            .iter()
            .map(|(a, b)| (a.to_string(), b.to_string()))
            .collect();
        let e =
            ros_environment_from(|k| owned.iter().find(|(n, _)| n == k).map(|(_, v)| v.clone()))
                .unwrap_err();
        assert!(e.to_string().contains(needle), "{e}");
    }
}

#[test]
fn static_peers_from_the_environment() {
    use node_runtime::static_peers_from;
    use std::net::IpAddr;
    let peers = |v: &str| {
        let v = v.to_owned();
        static_peers_from(move |k| (k == "ROS_STATIC_PEERS").then(|| v.clone()))
    };
    assert_eq!(static_peers_from(|_| None).unwrap(), Vec::<IpAddr>::new());
    assert_eq!(peers("").unwrap(), Vec::<IpAddr>::new());
    assert_eq!(
        peers("192.168.1.20; 10.0.0.7;;::1").unwrap(),
        ["192.168.1.20", "10.0.0.7", "::1"]
            .map(|a| a.parse::<IpAddr>().unwrap())
            .to_vec()
    );
    // A name that cannot resolve (RFC 6761 reserves .invalid) is named in the error.
    let e = peers("10.0.0.7;robot.invalid").unwrap_err().to_string();
    assert!(
        e.contains("ROS_STATIC_PEERS") && e.contains("`robot.invalid`"),
        "{e}"
    );
}
