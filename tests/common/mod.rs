//! What the end-to-end tests of the `biped` command share: where the repository, the
//! Python reference tools and the built binaries are, and a private network namespace for
//! every DDS participant (nothing leaves the machine).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
#![allow(dead_code)]

use std::path::PathBuf;
use std::process::Command;

pub mod cold_start;

/// The repository root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The venv's interpreter with rclpy and the reference tools: `BIPED_PYTHON`, else
/// `.venv/bin/biped-python` (scripts/setup-python-env makes it; scripts/test sets the
/// variable).
pub fn python() -> PathBuf {
    let p = std::env::var_os("BIPED_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join(".venv/bin/biped-python"));
    assert!(
        p.exists(),
        "no Python reference tools at {}: run scripts/setup-python-env (scripts/test does)",
        p.display()
    );
    p
}

/// Runs `tests/python/SCRIPT ARGS` in the venv with `input` on its standard input; it must
/// succeed (its standard error in the panic otherwise). Returns its standard output.
pub fn run_python(script: &str, args: &[&std::ffi::OsStr], input: &[u8]) -> Vec<u8> {
    use std::io::Write as _;
    let py = python();
    let path = root().join("tests/python").join(script);
    let mut child = Command::new(&py)
        .arg(&path)
        .args(args)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| {
            panic!(
                "cannot run {}: {e}; run scripts/setup-python-env",
                py.display()
            )
        });
    child
        .stdin
        .take()
        .expect("stdin is piped")
        .write_all(input)
        .unwrap_or_else(|e| panic!("{script} does not read its input: {e}"));
    let out = child.wait_with_output().expect("the script runs");
    assert!(
        out.status.success(),
        "{} {} failed ({}): {}\n(if rclpy or a message package is missing, run scripts/setup-python-env)",
        py.display(),
        path.display(),
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

/// The folder of `biped` and the node binaries, checked to hold them all.
pub fn bin_dir() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_BIN_EXE_biped"))
        .parent()
        .unwrap()
        .to_path_buf();
    for node in [
        "gait_planner",
        "ik_solver",
        "joint_bridge",
        "sim_bridge",
        "robot_state_publisher",
    ] {
        assert!(
            dir.join(node).is_file(),
            "node binary {node} not built in {}: run cargo build --workspace (scripts/test does)",
            dir.display()
        );
    }
    dir
}

/// `sh -c SCRIPT sh ARGS...` (add ARGS with `.arg`) in a new network namespace with only
/// loopback, multicast on, on `domain_id`, discovery restricted to this host.
pub fn in_netns(script: &str, domain_id: u32) -> Command {
    let mut c = Command::new("unshare");
    c.args([
        "-n",
        "sh",
        "-c",
        &format!(
            "ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo || exit 90\n{script}"
        ),
        "sh",
    ])
    .env("ROS_DOMAIN_ID", domain_id.to_string())
    .env("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    .env_remove("ROS_LOCALHOST_ONLY")
    .env_remove(node_runtime::LAUNCH_PARENT_ENV);
    c
}

/// The command `biped walk ARGS --out OUT` in a private network namespace (only loopback)
/// on `domain_id`, `biped walk` itself restricting discovery to the host. `unshare` and
/// `sh` exec, so the process started is `biped walk` itself.
pub fn biped_walk_command(domain_id: u32, out: &std::path::Path, args: &[&str]) -> Command {
    let mut c = Command::new("unshare");
    c.args(["-n", "sh", "-c", "ip link set lo up && exec \"$@\"", "sh"])
        .arg(bin_dir().join("biped"))
        .arg("walk")
        .args(args)
        .arg("--out")
        .arg(out)
        .env("ROS_DOMAIN_ID", domain_id.to_string())
        .env_remove("ROS_AUTOMATIC_DISCOVERY_RANGE");
    c
}

/// [`biped_walk_command`], run to its end.
pub fn biped_walk(domain_id: u32, out: &std::path::Path, args: &[&str]) -> std::process::Output {
    biped_walk_command(domain_id, out, args)
        .output()
        .expect("unshare runs (root needed for a private network namespace)")
}

/// [`biped_walk`], which must succeed (its output in the panic otherwise).
pub fn biped_walk_ok(domain_id: u32, out: &std::path::Path, args: &[&str]) {
    let o = biped_walk(domain_id, out, args);
    assert!(
        o.status.success(),
        "biped walk {args:?} failed:\n{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// `tests/python/SCRIPT` under the reference Python in a new network namespace
/// ([`in_netns`]); add its arguments with `.arg`, then [`json_of`].
pub fn python_in_netns(script: &str, domain_id: u32) -> Command {
    let mut c = in_netns("exec \"$@\"", domain_id);
    c.arg(python())
        .arg(root().join("tests/python").join(script));
    c
}

/// Runs `cmd`, which must succeed (else panics naming `what` with its stderr), and parses
/// the JSON it prints.
pub fn json_of(cmd: &mut Command, what: &str) -> serde_json::Value {
    let out = cmd
        .output()
        .expect("unshare runs (root needed for a private network namespace)");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{what} failed: {stderr}");
    serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("{what}: output is not JSON ({e}): {stderr}"))
}
