//! `biped plan` end to end: the CSV contract (header, units, every number agreeing with
//! forward kinematics of the URDF), the golden trajectory, and clear errors on bad input.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use ik_solver::{BipedModel, Side};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};

const HEADER: &str = "t,phase,support,base_x,base_y,base_z,base_yaw,l_ankle_x,l_ankle_y,l_ankle_z,r_ankle_x,r_ankle_y,r_ankle_z,com_x,com_y,com_z,margin";

use common::root;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("biped-test-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn biped(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_biped"))
        .args(args)
        .output()
        .expect("biped runs")
}

/// `biped plan ARGS --csv DIR/plan.csv --no-plots`, which must succeed; its CSV.
fn plan(dir: &Path, args: &[&str]) -> Csv {
    plan_with_output(dir, args).1
}

/// [`plan`], with what the command printed.
fn plan_with_output(dir: &Path, args: &[&str]) -> (std::process::Output, Csv) {
    let csv_path = dir.join("plan.csv");
    let mut all = vec!["plan"];
    all.extend_from_slice(args);
    all.extend(["--csv", csv_path.to_str().unwrap(), "--no-plots"]);
    let out = biped(&all);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = Csv::read(&csv_path);
    (out, csv)
}

struct Csv {
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl Csv {
    fn read(path: &Path) -> Self {
        let text = std::fs::read_to_string(path).unwrap();
        let mut lines = text.lines();
        let header = lines.next().unwrap().split(',').map(String::from).collect();
        let rows = lines
            .map(|l| l.split(',').map(String::from).collect())
            .collect();
        Self { header, rows }
    }
    fn col(&self, name: &str) -> usize {
        self.header
            .iter()
            .position(|h| h == name)
            .unwrap_or_else(|| panic!("no column {name}"))
    }
    fn num(&self, row: &[String], name: &str) -> f64 {
        row[self.col(name)].parse().unwrap()
    }
}

#[test]
fn csv_has_the_contract_header_and_agrees_with_forward_kinematics() {
    let slow = root().join("tests/data/gait_slow.yaml");
    let slow = slow.to_str().unwrap();
    let dir = tmp("fk");
    let csv_path = dir.join("plan.csv");
    let out = biped(&[
        "plan",
        "--params",
        slow,
        "--steps",
        "3",
        "--csv",
        csv_path.to_str().unwrap(),
        "--no-plots",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = Csv::read(&csv_path);
    let model = BipedModel::from_urdf_file(root().join("config/biped.urdf"), None).unwrap();
    let robot = model.robot();

    // Header: the fixed columns, then every movable joint by URDF name, in URDF order.
    assert_eq!(csv.header[..17].join(","), HEADER);
    let names: Vec<&str> = robot.dof_names().collect();
    assert_eq!(
        csv.header[17..],
        names.iter().map(|s| s.to_string()).collect::<Vec<_>>()
    );

    let mut phases: HashMap<String, usize> = HashMap::new();
    let mut prev_t = -1.0;
    for row in &csv.rows {
        let t = csv.num(row, "t");
        assert!(t > prev_t);
        prev_t = t;
        *phases.entry(row[1].clone()).or_default() += 1;
        assert!(
            ["double", "left", "right"].contains(&row[2].as_str()),
            "support {}",
            row[2]
        );
        let base = Isometry3::from_parts(
            Translation3::new(
                csv.num(row, "base_x"),
                csv.num(row, "base_y"),
                csv.num(row, "base_z"),
            ),
            UnitQuaternion::from_euler_angles(0.0, 0.0, csv.num(row, "base_yaw")),
        );
        let q: Vec<f64> = names.iter().map(|n| csv.num(row, n)).collect();
        let poses = robot.link_poses(&base, &q).unwrap();
        for (side, p) in [(Side::Left, "l"), (Side::Right, "r")] {
            let a = model.leg(side).ankle_world(robot, &poses);
            for (k, axis) in ["x", "y", "z"].iter().enumerate() {
                let v = csv.num(row, &format!("{p}_ankle_{axis}"));
                assert!(
                    (a[k] - v).abs() < 1e-9,
                    "t = {t}: {p}_ankle_{axis} {v} vs FK {}",
                    a[k]
                );
            }
            // Feet never below the floor (ankle-to-sole 0.03 m on this robot).
            assert!(a.z >= 0.03 - 1e-12);
        }
        let com = robot.center_of_mass(&poses);
        for (k, axis) in ["x", "y", "z"].iter().enumerate() {
            let v = csv.num(row, &format!("com_{axis}"));
            assert!(
                (com[k] - v).abs() < 1e-9,
                "t = {t}: com_{axis} {v} vs FK {}",
                com[k]
            );
        }
        // Single support: the margin is the distance to the nearest edge of the stance sole,
        // 0.10 x 0.06 m reaching 0.04 m behind and 0.06 m ahead of the ankle.
        let margin = csv.num(row, "margin");
        if row[2] != "double" {
            let p = &row[2][..1];
            let (ax, ay) = (
                csv.num(row, &format!("{p}_ankle_x")),
                csv.num(row, &format!("{p}_ankle_y")),
            );
            let (cx, cy) = (com.x - ax, com.y - ay);
            let want = (cx + 0.04).min(0.06 - cx).min(cy + 0.03).min(0.03 - cy);
            assert!(
                (margin - want).abs() < 1e-9,
                "t = {t}: margin {margin} vs {want}"
            );
        }
        assert!(margin > 0.0, "t = {t}: CoM outside");
    }
    for p in [
        "crouch",
        "shift",
        "half_step",
        "step",
        "final_half_step",
        "center",
    ] {
        assert!(phases.contains_key(p), "phase {p} missing");
    }
    // 3 steps of 0.045 m (the slow walk): feet end together 0.135 m ahead.
    let last = csv.rows.last().unwrap();
    assert!(
        (csv.num(last, "l_ankle_x") - 0.135).abs() < 1e-12
            && (csv.num(last, "r_ankle_x") - 0.135).abs() < 1e-12
    );
}

/// The OP3-layout robot's plan (hip yaw and roll apart, the pitch plane and the ankle roll
/// axis offset sideways) through Pinocchio, an independent implementation: its FK of the
/// planned joints puts each ankle point where the plan says, the soles level, and the CoM
/// where the plan says. The ankle point is 22 mm ahead of the ankle roll joint on its axis
/// (tests/data/make_op3_layout.py), a number of the robot, not of our code.
#[test]
fn the_op3_layout_plan_agrees_with_pinocchio() {
    const ANKLE_POINT_IN_FOOT_M: [f64; 3] = [0.022, 0.0, 0.0];
    let dir = tmp("op3-pin");
    let urdf = root().join("tests/data/op3_layout.urdf");
    let csv = plan(&dir, &["--robot", urdf.to_str().unwrap(), "--steps", "2"]);
    let joints: Vec<String> = csv.header[17..].to_vec();
    let rows: Vec<&Vec<String>> = csv.rows.iter().step_by(25).collect();
    assert!(rows.len() > 20);
    let requests: Vec<String> = rows
        .iter()
        .map(|row| {
            let q: Vec<String> = joints
                .iter()
                .map(|j| format!("\"{j}\": {:?}", csv.num(row, j)))
                .collect();
            format!(
                "{{\"base\": {{\"xyz\": [{:?}, {:?}, {:?}], \"rpy\": [0.0, 0.0, {:?}]}}, \"q\": {{{}}}, \"frames\": [\"l_foot\", \"r_foot\"]}}",
                csv.num(row, "base_x"),
                csv.num(row, "base_y"),
                csv.num(row, "base_z"),
                csv.num(row, "base_yaw"),
                q.join(", ")
            )
        })
        .collect();
    let out = common::run_python(
        "pin_reference.py",
        &[urdf.as_os_str()],
        format!("[{}]", requests.join(",")).as_bytes(),
    );
    let answers: Vec<serde_json::Value> = serde_json::from_slice(&out).unwrap();
    assert_eq!(answers.len(), rows.len());
    let mut worst = 0.0f64;
    for (row, ans) in rows.iter().zip(&answers) {
        let t = csv.num(row, "t");
        for (foot, p) in [("l_foot", "l"), ("r_foot", "r")] {
            let f = &ans["frames"][foot];
            let xyz: Vec<f64> = (0..3).map(|i| f["xyz"][i].as_f64().unwrap()).collect();
            let r = |i: usize, j: usize| f["rotation"][i][j].as_f64().unwrap();
            for (k, axis) in ["x", "y", "z"].iter().enumerate() {
                let a = xyz[k]
                    + (0..3)
                        .map(|j| r(k, j) * ANKLE_POINT_IN_FOOT_M[j])
                        .sum::<f64>();
                let want = csv.num(row, &format!("{p}_ankle_{axis}"));
                worst = worst.max((a - want).abs());
                assert!(
                    (a - want).abs() < 1e-6,
                    "t = {t}: {p}_ankle_{axis} planned {want}, Pinocchio {a}"
                );
            }
            // Level: the foot's z axis is the world's.
            assert!(
                (r(2, 2) - 1.0).abs() < 1e-9,
                "t = {t}: {foot} tilted, R22 = {}",
                r(2, 2)
            );
        }
        for (k, axis) in ["x", "y", "z"].iter().enumerate() {
            let c = ans["com"][k].as_f64().unwrap();
            let want = csv.num(row, &format!("com_{axis}"));
            assert!(
                (c - want).abs() < 1e-6,
                "t = {t}: com_{axis} planned {want}, Pinocchio {c}"
            );
        }
    }
    eprintln!(
        "{} ticks against Pinocchio; worst ankle error {worst:e} m",
        rows.len()
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

fn compare_csv(got: &Csv, want: &Csv) -> Result<(), String> {
    if got.header != want.header {
        return Err("header differs".into());
    }
    if got.rows.len() != want.rows.len() {
        return Err(format!(
            "{} rows, golden has {}",
            got.rows.len(),
            want.rows.len()
        ));
    }
    for (i, (g, w)) in got.rows.iter().zip(&want.rows).enumerate() {
        for (k, (a, b)) in g.iter().zip(w).enumerate() {
            let same = match (a.parse::<f64>(), b.parse::<f64>()) {
                (Ok(x), Ok(y)) => (x - y).abs() <= 1e-9,
                _ => a == b,
            };
            if !same {
                return Err(format!(
                    "row {} column {}: {a} vs golden {b}",
                    i + 1,
                    got.header[k]
                ));
            }
        }
    }
    Ok(())
}

/// The default robot's 2-step walk at 20 Hz, compared with `tests/golden/plan_default_2steps_20hz.csv`
/// to 1e-9. Regenerate on purpose only: `BIPED_BLESS=1 cargo test --test plan_cli golden`.
#[test]
fn golden_trajectory_of_the_default_robot() {
    let golden = root().join("tests/golden/plan_default_2steps_20hz.csv");
    let dir = tmp("golden");
    let csv_path = dir.join("plan.csv");
    let params = root().join("tests/data/golden_params.yaml");
    let out = biped(&[
        "plan",
        "--steps",
        "2",
        "--params",
        params.to_str().unwrap(),
        "--csv",
        csv_path.to_str().unwrap(),
        "--no-plots",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    if std::env::var_os("BIPED_BLESS").is_some() {
        std::fs::copy(&csv_path, &golden).unwrap();
        eprintln!("golden trajectory rewritten: {}", golden.display());
        return;
    }
    assert!(
        golden.exists(),
        "no golden file {}; create it on purpose with BIPED_BLESS=1",
        golden.display()
    );
    if let Err(e) = compare_csv(&Csv::read(&csv_path), &Csv::read(&golden)) {
        panic!(
            "the plan differs from the golden trajectory: {e}\nIf the change is intended, regenerate it with BIPED_BLESS=1 and review the diff."
        );
    }
}

#[test]
fn plots_are_written_beside_the_csv() {
    let dir = tmp("plots");
    let csv_path = dir.join("plan.csv");
    let out = biped(&["plan", "--steps", "2", "--csv", csv_path.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for f in ["top_view.svg", "swing_curve.svg", "joint_angles.svg"] {
        let text = std::fs::read_to_string(dir.join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
        assert!(
            text.starts_with("<svg") && text.contains("</svg>") && text.len() > 2000,
            "{f} is not a drawing"
        );
    }
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("planned 2 steps") && stdout.contains("top_view.svg"),
        "{stdout}"
    );
}

fn fails_naming(args: &[&str], needles: &[&str]) {
    let out = biped(args);
    assert!(!out.status.success(), "{args:?} should fail");
    let err = String::from_utf8_lossy(&out.stderr);
    for n in needles {
        assert!(
            err.contains(n),
            "{args:?}: error does not name {n:?}: {err}"
        );
    }
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn bad_input_gets_a_clear_error() {
    let dir = tmp("bad");
    let csv = dir.join("x.csv");
    let csv = csv.to_str().unwrap();
    fails_naming(
        &["plan", "--robot", "/nonexistent/robot.urdf", "--csv", csv],
        &["/nonexistent/robot.urdf"],
    );
    let bad_params = dir.join("bad.yaml");
    std::fs::write(
        &bad_params,
        "gait_planner:\n  ros__parameters:\n    step_lenght_m: 0.03\n",
    )
    .unwrap();
    fails_naming(
        &[
            "plan",
            "--params",
            bad_params.to_str().unwrap(),
            "--csv",
            csv,
        ],
        &["step_lenght_m", "bad.yaml"],
    );
    let unstable = dir.join("unstable.yaml");
    std::fs::write(
        &unstable,
        "gait_planner:\n  ros__parameters:\n    min_com_margin_m: 0.04\n",
    )
    .unwrap();
    fails_naming(
        &["plan", "--params", unstable.to_str().unwrap(), "--csv", csv],
        &["shift", "CoM margin", "0.0400"],
    );
    let one_leg = dir.join("one_leg.urdf");
    let text = std::fs::read_to_string(root().join("config/biped.urdf"))
        .unwrap()
        .replace(
            "name=\"l_knee\" type=\"revolute\"",
            "name=\"l_knee\" type=\"fixed\"",
        );
    std::fs::write(&one_leg, text).unwrap();
    fails_naming(
        &["plan", "--robot", one_leg.to_str().unwrap(), "--csv", csv],
        &["not a supported biped", "1 leg chain"],
    );
    fails_naming(&["plan", "--steps", "0", "--csv", csv], &["--steps"]);
    assert!(!Path::new(csv).exists(), "nothing written on error");
}

/// `--twist` walks sideways and backward: the feet end where the step limits of the default
/// robot's slow walk (tests/data/gait_slow.yaml) put them (side step 0.1 x leg = 18 mm per step, hand-computed; the back step is a
/// velocity x the 3 s step period), pictures and all; a turn or a NaN is refused by name.
#[test]
fn twist_walks_sideways_and_backward() {
    let slow = root().join("tests/data/gait_slow.yaml");
    let slow = slow.to_str().unwrap();
    let dir = tmp("twist");
    let side = dir.join("side/plan.csv");
    let out = biped(&[
        "plan",
        "--params",
        slow,
        "--steps",
        "4",
        "--twist",
        "0,0.006,0",
        "--csv",
        side.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{out:?}");
    // Exactly on the side limit: no warning about scaling.
    assert!(!String::from_utf8_lossy(&out.stderr).contains("warning"));
    let csv = Csv::read(&side);
    let (first, last) = (&csv.rows[0], csv.rows.last().unwrap());
    for col in ["l_ankle_y", "r_ankle_y"] {
        let moved = csv.num(last, col) - csv.num(first, col);
        assert!((moved - 4.0 * 0.018).abs() < 1e-12, "{col} moved {moved}");
    }
    for col in ["l_ankle_x", "r_ankle_x"] {
        assert!((csv.num(last, col) - csv.num(first, col)).abs() < 1e-12);
    }
    assert!(dir.join("side/top_view.svg").exists());

    let back = dir.join("back/plan.csv");
    let out = biped(&[
        "plan",
        "--params",
        slow,
        "--steps",
        "3",
        "--twist=-0.01,0,0",
        "--csv",
        back.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{out:?}");
    let csv = Csv::read(&back);
    let last = csv.rows.last().unwrap();
    for col in ["l_ankle_x", "r_ankle_x"] {
        assert!((csv.num(last, col) + 0.09).abs() < 1e-12, "{col}");
    }
    // Beyond the limit: scaled, with a warning naming what is walked.
    let out = biped(&[
        "plan",
        "--params",
        slow,
        "--steps",
        "1",
        "--twist",
        "0,0.5,0",
        "--csv",
        dir.join("fast/plan.csv").to_str().unwrap(),
        "--no-plots",
    ]);
    assert!(out.status.success(), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("beyond the step limits") && err.contains("0.0060"),
        "{err}"
    );

    let csv = dir.join("x.csv");
    let csv = csv.to_str().unwrap();
    fails_naming(
        &["plan", "--twist", "0,0,0.2", "--csv", csv],
        &["angular.z = 0.2", "no hip yaw"],
    );
    fails_naming(
        &["plan", "--twist", "0,nan,0", "--csv", csv],
        &["vy", "nan"],
    );
    fails_naming(&["plan", "--twist", "0,1", "--csv", csv], &["vx,vy,wz"]);
    assert!(!Path::new(csv).exists(), "nothing written on error");
}

/// A robot with hip yaw joints turns (its slow walk, tests/data/biped6_slow.yaml): 4 steps of 0.03 rad/s x the 3 s step period = 0.09 rad
/// per step end with the pelvis and both feet turned 0.36 rad (the side of the turn opens
/// by twice the step at each of its swings, the other closes parallel).
#[test]
fn twist_turns_a_robot_with_hip_yaw() {
    let slow = root().join("tests/data/biped6_slow.yaml");
    let slow = slow.to_str().unwrap();
    let dir = tmp("turn");
    let csv_path = dir.join("plan.csv");
    let robot = root().join("tests/data/biped6_renamed.urdf");
    let out = biped(&[
        "plan",
        "--params",
        slow,
        "--robot",
        robot.to_str().unwrap(),
        "--steps",
        "4",
        "--twist",
        "0,0,0.03",
        "--csv",
        csv_path.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{out:?}");
    let csv = Csv::read(&csv_path);
    let last = csv.rows.last().unwrap();
    let yaw = csv.num(last, "base_yaw");
    assert!((yaw - 4.0 * 0.09).abs() < 1e-9, "base_yaw {yaw}");
    assert!(dir.join("top_view.svg").exists());
}

/// The duration `--fastest` printed for `key` (shift, step, crouch) in its line
/// "fastest timing: shift 0.72 s (Zmp), step 0.58 s (...), crouch 0.31 s (...); ...".
fn fastest_secs(stdout: &str, key: &str) -> f64 {
    secs_after(stdout, "fastest timing:", key)
}

/// The `KEY 0.780 s` duration on the line of `stdout` that starts with `prefix`.
fn secs_after(stdout: &str, prefix: &str, key: &str) -> f64 {
    let line = stdout
        .lines()
        .find(|l| l.starts_with(prefix))
        .unwrap_or_else(|| panic!("{stdout}"));
    line.split(&format!("{key} "))
        .nth(1)
        .and_then(|r| r.split(" s").next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no {key} duration in {line}"))
}

/// The fast parameter files hold the fastest timing of their own steps: `--fastest` on each
/// finds the durations written in it (so a planner change that moves the bound shows here),
/// and says what pausing anywhere costs.
#[test]
fn the_fast_parameter_files_hold_the_fastest_timing_of_their_steps() {
    let dir = tmp("fast-files");
    let op3 = root().join("tests/data/op3_layout.urdf");
    for (file, robot) in [
        (root().join("config/gait_fast.yaml"), None),
        (root().join("tests/data/op3_layout_fast.yaml"), Some(&op3)),
    ] {
        let mut args = vec![
            "--steps",
            "2",
            "--fastest",
            "--params",
            file.to_str().unwrap(),
        ];
        if let Some(r) = robot {
            args.extend(["--robot", r.to_str().unwrap()]);
        }
        let (out, _) = plan_with_output(&dir, &args);
        let stdout = String::from_utf8_lossy(&out.stdout);
        let text = std::fs::read_to_string(&file).unwrap();
        for key in ["shift", "step", "crouch"] {
            let found = fastest_secs(&stdout, key);
            let written: f64 = text
                .lines()
                .find_map(|l| l.trim().strip_prefix(&format!("{key}_duration_s: ")))
                .unwrap_or_else(|| panic!("{}: no {key}_duration_s", file.display()))
                .parse()
                .unwrap();
            assert!(
                (found - written).abs() < 1e-9,
                "{}: {key} {written} s written, {found} s found: {stdout}",
                file.display()
            );
        }
        assert!(
            stdout.contains("pausing anywhere within 0.25 s costs"),
            "{stdout}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--fastest` prints the durations it found and plans with them: the CSV's phases last
/// that long (ticks at 100 Hz), and the warning (no torque budget without a servo model;
/// not for hardware) goes to stderr.
#[test]
fn fastest_plans_with_the_timing_it_prints() {
    let dir = tmp("fastest");
    let (out, csv) = plan_with_output(&dir, &["--steps", "4", "--fastest"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("no torque budget") && stderr.contains("Not for hardware"),
        "{stderr}"
    );
    let secs = |key: &str| fastest_secs(&stdout, key);
    let (shift, step, crouch) = (secs("shift"), secs("step"), secs("crouch"));
    assert!(shift < 2.0 && step < 1.0 && crouch < 1.0, "{stdout}");
    assert_phases_last(&csv, [shift, step, crouch], &stdout);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The phases of a 4-step plan's CSV last `[shift, step, crouch]` seconds.
fn assert_phases_last(csv: &Csv, [shift, step, crouch]: [f64; 3], line: &str) {
    let phase = csv.col("phase");
    let ticks = |name: &str| csv.rows.iter().filter(|r| r[phase] == name).count();
    // Each phase's ticks are (start, end]; the crouch also has its t = 0 tick. 4 steps:
    // 5 shifts and the centring (shift duration), 1 half step, 3 steps, 1 final half step.
    let n = |s: f64| (s * 100.0).round() as usize;
    assert_eq!(ticks("crouch"), n(crouch) + 1, "{line}");
    assert_eq!(ticks("shift"), 5 * n(shift), "{line}");
    assert_eq!(ticks("center"), n(shift), "{line}");
    assert_eq!(ticks("step"), 3 * n(step), "{line}");
    assert_eq!(ticks("half_step"), n(step), "{line}");
}

/// Durations left at 0 in the parameter file are the fastest the checks allow: `biped plan`
/// says so and plans with the durations `--fastest` finds from the defaults' 2 s / 1 s / 1 s;
/// one set by hand beside them stays.
#[test]
fn durations_left_at_auto_plan_at_the_fastest_timing() {
    let dir = tmp("auto-durations");
    let (fast, _) = plan_with_output(&dir, &["--steps", "4", "--fastest"]);
    let fast = String::from_utf8_lossy(&fast.stdout).into_owned();
    let want = ["shift", "step", "crouch"].map(|k| fastest_secs(&fast, k));
    let file = dir.join("auto.yaml");
    for (hand_shift, text) in [(None, ""), (Some(1.5), "    shift_duration_s: 1.5\n")] {
        std::fs::write(
            &file,
            format!(
                "gait_planner:\n  ros__parameters:\n    step_duration_s: 0.0\n    crouch_duration_s: 0.0\n{}",
                if text.is_empty() { "    shift_duration_s: 0.0\n" } else { text }
            ),
        )
        .unwrap();
        let (out, csv) =
            plan_with_output(&dir, &["--steps", "4", "--params", file.to_str().unwrap()]);
        let stdout = String::from_utf8_lossy(&out.stdout);
        let prefix = "durations left at 0 (auto), the fastest the checks allow:";
        let got = ["step", "crouch"].map(|k| secs_after(&stdout, prefix, k));
        assert_eq!(got, [want[1], want[2]], "{stdout}\n{fast}");
        let mut expect = want;
        if let Some(s) = hand_shift {
            // Set by hand: used, and not among the auto ones printed.
            expect[0] = s;
            let line = stdout.lines().find(|l| l.starts_with(prefix)).unwrap();
            assert!(!line.contains("shift"), "{line}");
        } else {
            assert_eq!(secs_after(&stdout, prefix, "shift"), want[0], "{stdout}");
        }
        assert_phases_last(&csv, expect, &stdout);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--fastest-walk --write-params FILE`: prints every walk tried and the fastest, plans it,
/// and writes a parameter file that plans the same walk again (the same CSV); without
/// `--fastest`/`--fastest-walk` there is nothing to write, and it is refused.
#[test]
fn the_fastest_walk_is_written_as_a_parameter_file_that_plans_it_again() {
    let dir = tmp("fastest-walk");
    let file = dir.join("fastest_walk.yaml");
    let (out, csv) = plan_with_output(
        &dir,
        &[
            "--steps",
            "4",
            "--fastest-walk",
            "--write-params",
            file.to_str().unwrap(),
        ],
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    let tried = stdout.lines().filter(|l| l.starts_with("  step ")).count();
    // The 5 x 3 grid, and 3 bisections of the step when the next longer one was refused.
    assert!((15..=18).contains(&tried), "{stdout}");
    let best = stdout
        .lines()
        .find(|l| l.starts_with("fastest walk: "))
        .unwrap_or_else(|| panic!("{stdout}"));
    // The best line's speed is the largest of the walks accepted.
    let speed = |l: &str| -> f64 {
        l.split(" m/s planned")
            .next()
            .unwrap()
            .rsplit(' ')
            .next()
            .unwrap()
            .parse()
            .unwrap()
    };
    let top = stdout
        .lines()
        .filter(|l| l.starts_with("  step ") && l.contains("m/s planned"))
        .map(speed)
        .fold(0.0, f64::max);
    assert!((speed(best) - top).abs() < 1e-4, "{stdout}");
    let again = plan(&dir, &["--steps", "4", "--params", file.to_str().unwrap()]);
    assert_eq!(again.rows, csv.rows, "the written file plans the same walk");
    let text = std::fs::read_to_string(&file).unwrap();
    assert!(
        text.contains("step_length_m: ")
            && text.starts_with("# Written by `biped plan --fastest-walk` for biped20"),
        "{text}"
    );
    fails_naming(
        &[
            "plan",
            "--write-params",
            file.to_str().unwrap(),
            "--csv",
            dir.join("x.csv").to_str().unwrap(),
        ],
        &["--write-params", "--fastest"],
    );
    let _ = std::fs::remove_dir_all(&dir);
}
