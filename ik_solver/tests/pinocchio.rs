//! Forward kinematics, total mass and whole-body centre of mass against Pinocchio, an
//! independent implementation (tests/python/pin_reference.py, run in the venv that
//! scripts/setup-python-env builds), plus one centre of mass worked out by hand.
//!
//! The venv is required: without it these tests fail and say how to make it.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::{TEST_BIPED6, TEST_OP3_LAYOUT};

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use ik_solver::{JointKind, RobotModel};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion};
use serde::Deserialize;

const WORKSPACE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
const CASES: usize = 20;
const POS_TOL_M: f64 = 1e-9;
const ROT_TOL: f64 = 1e-9;
const MASS_TOL_KG: f64 = 1e-12;

// ---------------------------------------------------------------- the reference

#[derive(Debug, Deserialize)]
struct FrameAnswer {
    xyz: [f64; 3],
    rotation: [[f64; 3]; 3],
}

#[derive(Debug, Deserialize)]
struct Answer {
    com: [f64; 3],
    mass: f64,
    frames: BTreeMap<String, FrameAnswer>,
}

/// The venv's interpreter: `BIPED_PYTHON` if set, else `<workspace>/.venv/bin/python`.
fn python() -> PathBuf {
    match std::env::var_os("BIPED_PYTHON") {
        Some(p) => PathBuf::from(p),
        None => {
            let p = Path::new(WORKSPACE).join(".venv/bin/python");
            assert!(
                p.exists(),
                "{} does not exist: run scripts/setup-python-env (it builds the venv with Pinocchio \
                 that these tests compare against), or set BIPED_PYTHON to a python that has `pin` installed",
                p.display()
            );
            p
        }
    }
}

/// Runs pin_reference.py once on a list of requests (JSON text) and returns its answers.
fn pinocchio(urdf_path: &Path, requests_json: &str) -> Vec<Answer> {
    let py = python();
    let script = Path::new(WORKSPACE).join("tests/python/pin_reference.py");
    let mut child = Command::new(&py)
        .arg(&script)
        .arg(urdf_path)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
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
        .unwrap()
        .write_all(requests_json.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "{} {} {} failed ({}): {}\n(if pinocchio is missing, run scripts/setup-python-env)",
        py.display(),
        script.display(),
        urdf_path.display(),
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    // JSON is YAML: the YAML parser that is already a dev-dependency reads the answer.
    let text = String::from_utf8(out.stdout).unwrap();
    serde_norway::from_str(&text)
        .unwrap_or_else(|e| panic!("pin_reference answer does not parse: {e}\n{text}"))
}

// ---------------------------------------------------------------- random inputs

/// xorshift64*: a small seeded generator, enough for spreading test points.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [lo, hi).
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        let unit = (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        lo + (hi - lo) * unit
    }
}

struct Case {
    xyz: [f64; 3],
    rpy: [f64; 3],
    q: Vec<f64>,
}

impl Case {
    fn base(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(self.xyz[0], self.xyz[1], self.xyz[2]),
            UnitQuaternion::from_euler_angles(self.rpy[0], self.rpy[1], self.rpy[2]),
        )
    }
}

fn random_cases(robot: &RobotModel, seed: u64) -> Vec<Case> {
    let mut rng = Rng(seed);
    (0..CASES)
        .map(|_| {
            let xyz = [0; 3].map(|_| rng.uniform(-0.5, 0.5));
            let rpy = [0; 3].map(|_| rng.uniform(-0.5, 0.5));
            let q = robot
                .dof_joints()
                .iter()
                .map(|&j| {
                    let joint = &robot.joints()[j];
                    let lim = joint.limits.unwrap();
                    match joint.kind {
                        JointKind::Continuous => {
                            rng.uniform(-std::f64::consts::PI, std::f64::consts::PI)
                        }
                        _ => rng.uniform(lim.lower, lim.upper),
                    }
                })
                .collect();
            Case { xyz, rpy, q }
        })
        .collect()
}

fn json_name(s: &str) -> String {
    assert!(
        s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_'),
        "name {s:?} needs JSON escaping"
    );
    format!("\"{s}\"")
}

fn json_vec(v: &[f64]) -> String {
    // `{:?}` prints the shortest representation that reads back to the same f64.
    format!(
        "[{}]",
        v.iter()
            .map(|x| format!("{x:?}"))
            .collect::<Vec<_>>()
            .join(", ")
    )
}

fn requests_json(robot: &RobotModel, cases: &[Case]) -> String {
    let frames: Vec<String> = robot.links().iter().map(|l| json_name(&l.name)).collect();
    let frames = frames.join(", ");
    let reqs: Vec<String> = cases
        .iter()
        .map(|c| {
            let q: Vec<String> = robot
                .dof_names()
                .zip(&c.q)
                .map(|(n, v)| format!("{}: {v:?}", json_name(n)))
                .collect();
            format!(
                "{{\"base\": {{\"xyz\": {}, \"rpy\": {}}}, \"q\": {{{}}}, \"frames\": [{frames}]}}",
                json_vec(&c.xyz),
                json_vec(&c.rpy),
                q.join(", ")
            )
        })
        .collect();
    format!("[{}]", reqs.join(",\n"))
}

// ---------------------------------------------------------------- the comparison

fn compare_with_pinocchio(what: &str, urdf_text: &str, urdf_path: &Path, seed: u64) {
    let robot = RobotModel::from_urdf_str(urdf_text).unwrap();
    let cases = random_cases(&robot, seed);
    let answers = pinocchio(urdf_path, &requests_json(&robot, &cases));
    assert_eq!(answers.len(), cases.len());

    let mut worst = (0.0f64, 0.0f64, 0.0f64);
    for (k, (case, ans)) in cases.iter().zip(&answers).enumerate() {
        let dm = (robot.total_mass_kg() - ans.mass).abs();
        assert!(
            dm < MASS_TOL_KG,
            "{what} case {k}: mass {} vs Pinocchio {}",
            robot.total_mass_kg(),
            ans.mass
        );

        let poses = robot.link_poses(&case.base(), &case.q).unwrap();
        let com = robot.center_of_mass(&poses);
        let dc = (com - Point3::from(ans.com)).norm();
        assert!(
            dc < POS_TOL_M,
            "{what} case {k}: CoM {com:?} vs Pinocchio {:?} ({dc:e} m)",
            ans.com
        );

        assert_eq!(ans.frames.len(), robot.links().len());
        for (link, pose) in robot.links().iter().zip(&poses) {
            let want = &ans.frames[&link.name];
            let dp = (pose.translation.vector - nalgebra::Vector3::from(want.xyz)).norm();
            assert!(
                dp < POS_TOL_M,
                "{what} case {k}: link `{}` at {:?}, Pinocchio {:?} ({dp:e} m)",
                link.name,
                pose.translation.vector,
                want.xyz
            );
            let r = pose.rotation.to_rotation_matrix();
            let dr = (0..3)
                .flat_map(|i| (0..3).map(move |j| (i, j)))
                .map(|(i, j)| (r[(i, j)] - want.rotation[i][j]).abs())
                .fold(0.0, f64::max);
            assert!(
                dr < ROT_TOL,
                "{what} case {k}: link `{}` rotation {r} vs Pinocchio {:?} ({dr:e})",
                link.name,
                want.rotation
            );
            worst = (worst.0.max(dp), worst.1.max(dr), worst.2.max(dc));
        }
    }
    // The cases must actually move the links: a base pose and joints far from zero.
    let spread = cases
        .iter()
        .map(|c| c.q.iter().fold(0.0f64, |m, v| m.max(v.abs())))
        .fold(0.0, f64::max);
    assert!(
        spread > 0.5,
        "{what}: random joint values stay near zero ({spread})"
    );
    eprintln!(
        "{what}: {} cases; worst position {:e} m, rotation {:e}, CoM {:e} m",
        cases.len(),
        worst.0,
        worst.1,
        worst.2
    );
}

#[test]
fn default_robot_fk_and_com_match_pinocchio() {
    let path = Path::new(WORKSPACE).join("config/biped.urdf");
    assert_eq!(
        std::fs::read_to_string(&path).unwrap(),
        ik_solver::DEFAULT_URDF
    );
    compare_with_pinocchio(
        "biped20",
        ik_solver::DEFAULT_URDF,
        &path,
        0x9E37_79B9_7F4A_7C15,
    );
}

#[test]
fn six_joint_test_robot_fk_and_com_match_pinocchio() {
    let path = Path::new(WORKSPACE).join("tests/data/biped6_renamed.urdf");
    compare_with_pinocchio("test_biped6", TEST_BIPED6, &path, 0xD1B5_4A32_D192_ED03);
}

/// Non-zero rpy on joints and inertials, oblique unit axes, continuous and prismatic joints,
/// a massless link and a massive link behind a fixed joint: what the two bipeds (all rpy
/// zero, axes along x/y/z, revolute only) do not exercise.
const TWISTED_URDF: &str = r#"<?xml version="1.0"?>
<robot name="twisted">
  <link name="body">
    <inertial><origin xyz="0.01 -0.02 0.03" rpy="0.1 0.2 0.3"/><mass value="1.5"/>
      <inertia ixx="0.01" ixy="0.001" ixz="0" iyy="0.012" iyz="0.0005" izz="0.015"/></inertial>
  </link>
  <joint name="j_oblique" type="revolute">
    <parent link="body"/><child link="arm"/>
    <origin xyz="0.1 0.05 -0.02" rpy="0.3 -0.2 0.5"/>
    <axis xyz="0.6 0 0.8"/>
    <limit lower="-1.5" upper="1.2" effort="1" velocity="1"/>
  </joint>
  <link name="arm">
    <inertial><origin xyz="0 0 -0.08" rpy="0 0.4 0"/><mass value="0.4"/>
      <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.002" iyz="0" izz="0.0005"/></inertial>
  </link>
  <joint name="j_spin" type="continuous">
    <parent link="arm"/><child link="wheel"/>
    <origin xyz="0 0.02 -0.16" rpy="-0.7 0 0.25"/>
    <axis xyz="0 -0.6 0.8"/>
    <limit effort="1" velocity="1"/>
  </joint>
  <link name="wheel">
    <inertial><origin xyz="0.03 0 0.01" rpy="0 0 0"/><mass value="0.25"/>
      <inertia ixx="0.0004" ixy="0" ixz="0" iyy="0.0004" iyz="0" izz="0.0007"/></inertial>
  </link>
  <joint name="j_slide" type="prismatic">
    <parent link="body"/><child link="slider"/>
    <origin xyz="-0.05 0 0.1" rpy="0 0.6 -0.3"/>
    <axis xyz="0 0.8 0.6"/>
    <limit lower="-0.05" upper="0.12" effort="10" velocity="0.5"/>
  </joint>
  <link name="slider"/>
  <joint name="j_bolted" type="fixed">
    <parent link="slider"/><child link="payload"/>
    <origin xyz="0.02 0.03 0.04" rpy="1.0 0.2 -0.4"/>
  </joint>
  <link name="payload">
    <inertial><origin xyz="0.05 0 -0.01" rpy="0 0 1"/><mass value="0.7"/>
      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial>
  </link>
</robot>
"#;

#[test]
fn twisted_tree_fk_and_com_match_pinocchio() {
    let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join("pinocchio_twisted.urdf");
    std::fs::write(&path, TWISTED_URDF).unwrap();
    let robot = RobotModel::from_urdf_str(TWISTED_URDF).unwrap();
    let kinds: Vec<JointKind> = robot.joints().iter().map(|j| j.kind).collect();
    assert_eq!(
        kinds,
        [
            JointKind::Revolute,
            JointKind::Continuous,
            JointKind::Prismatic,
            JointKind::Fixed
        ]
    );
    compare_with_pinocchio("twisted", TWISTED_URDF, &path, 0x0123_4567_89AB_CDEF);
}

// ---------------------------------------------------------------- by hand

/// Three links: `a` (1 kg, CoM 0.1 above its origin), revolute `j` about z at (0.1, 0, 0)
/// to `b` (3 kg, CoM (0.2, 0, 0.05), inertial rpy that must not move it), fixed `f` at
/// (0, 0.1, 0) turned 90° about z to `c` (2 kg, CoM 0.1 along c's x).
const HAND_URDF: &str = r#"<?xml version="1.0"?>
<robot name="hand">
  <link name="a">
    <inertial><origin xyz="0 0 0.1"/><mass value="1"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
  <joint name="j" type="revolute">
    <parent link="a"/><child link="b"/>
    <origin xyz="0.1 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/>
  </joint>
  <link name="b">
    <inertial><origin xyz="0.2 0 0.05" rpy="0.3 0 0"/><mass value="3"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
  <joint name="f" type="fixed">
    <parent link="b"/><child link="c"/>
    <origin xyz="0 0.1 0" rpy="0 0 1.5707963267948966"/>
  </joint>
  <link name="c">
    <inertial><origin xyz="0.1 0 0"/><mass value="2"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
</robot>
"#;

#[test]
fn center_of_mass_of_a_three_link_robot_by_hand() {
    // j = 30° (pi/6): cos = sqrt(3)/2 = 0.8660254037844386, sin = 0.5; base at the identity.
    //   a's CoM: (0, 0, 0.1).
    //   b's CoM: (0.1, 0, 0) + Rz(30°) (0.2, 0, 0.05) = (0.1 + 0.2 cos, 0.2 sin, 0.05)
    //          = (0.27320508075688773, 0.1, 0.05).
    //   c's CoM in b: (0, 0.1, 0) + Rz(90°) (0.1, 0, 0) = (0, 0.2, 0);
    //          in the world: (0.1, 0, 0) + Rz(30°) (0, 0.2, 0) = (0.1 - 0.2 sin, 0.2 cos, 0)
    //          = (0, 0.17320508075688773, 0).
    //   Total 6 kg. CoM = (1 a + 3 b + 2 c) / 6:
    //     x = 3 * 0.27320508075688773 / 6 = 0.13660254037844388
    //     y = (0.3 + 2 * 0.17320508075688773) / 6 = 0.10773502691896258
    //     z = (0.1 + 0.15) / 6 = 0.041666666666666664
    let robot = RobotModel::from_urdf_str(HAND_URDF).unwrap();
    assert!((robot.total_mass_kg() - 6.0).abs() < 1e-15);
    let q = [std::f64::consts::FRAC_PI_6];
    let poses = robot.link_poses(&Isometry3::identity(), &q).unwrap();
    let com = robot.center_of_mass(&poses);
    let want = Point3::new(
        0.13660254037844388,
        0.10773502691896258,
        0.041666666666666664,
    );
    assert!((com - want).norm() < 1e-12, "CoM {com:?}, by hand {want:?}");

    // Moving the base by a pure translation moves the CoM by exactly that translation.
    let shift = Translation3::new(0.5, -0.25, 1.0);
    let poses = robot
        .link_poses(
            &Isometry3::from_parts(shift, UnitQuaternion::identity()),
            &q,
        )
        .unwrap();
    let com = robot.center_of_mass(&poses);
    let want = Point3::new(0.6366025403784439, -0.14226497308103742, 1.0416666666666667);
    assert!(
        (com - want).norm() < 1e-12,
        "shifted CoM {com:?}, by hand {want:?}"
    );

    // The subtree below j (b and c, 5 kg): (3 b + 2 c) / 5 at the identity base
    //   = (0.8196152422706632 / 5, (0.3 + 0.34641016151377546) / 5, 0.15 / 5)
    //   = (0.16392304845413264, 0.1292820323027551, 0.03).
    let poses = robot.link_poses(&Isometry3::identity(), &q).unwrap();
    let (m, c) = robot.subtree_mass_and_com(&poses, robot.joint_index("j").unwrap());
    assert!((m - 5.0).abs() < 1e-15);
    let want = Point3::new(0.16392304845413264, 0.1292820323027551, 0.03);
    assert!(
        (c - want).norm() < 1e-12,
        "subtree CoM {c:?}, by hand {want:?}"
    );
}

#[test]
fn op3_layout_test_robot_fk_and_com_match_pinocchio() {
    let path = Path::new(WORKSPACE).join("tests/data/op3_layout.urdf");
    compare_with_pinocchio("op3_layout", TEST_OP3_LAYOUT, &path, 0x94D0_49BB_1331_11EB);
}
