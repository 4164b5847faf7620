//! Record in simulation, replay `/joint_commands` into the serial backend: the positions an
//! emulated Dynamixel 2.0 board receives are the recorded commands through the calibration.
//!
//! 1. `biped walk --steps 2 --real-time --settle 5 --bag BAG` in a private network namespace
//!    (loopback only, ROS_DOMAIN_ID 71, ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) records the
//!    simulated walk, paced against the wall clock (the recorded timing is about one a robot
//!    could follow; the simulator catches up after a stall, so stretches of it run faster);
//!    a 5 s settle, so the first recorded pose (standing) lasts longer than the joint
//!    bridge's 2 s start ramp.
//! 2. tests/python/bag_check.py --strict --dump reads the bag with readers that are not ours:
//!    the recorded `/joint_commands` the assertions compare against.
//! 3. A board emulator (joint_bridge/tests/support) on a pseudo-terminal, its servos at a
//!    crouched pose; then, in one new network namespace, the `joint_bridge` node
//!    (`backend:=serial`, the parameters `biped launch --backend serial` passes, its other
//!    parameters at their defaults: 100 Hz, 2 s start ramp, 0.25 s watchdog holding the
//!    pose) and, once it is ready, `biped replay BAG --topics /joint_commands`; then SIGINT
//!    to the bridge.
//! 4. The goal packets the board received, checked against the calibration applied here to
//!    the recorded angles (zero + direction × units_per_rad × angle, clamped to min/max, read
//!    from config/calibration_dynamixel2.yaml by this test), within one tick.
//!
//! The bridge ticks on its own clock, so goals follow the recorded commands in order, some
//! skipped or repeated. A goal that is no recorded command must be the bridge's velocity
//! limit at work (commands replayed in a burst, as the recorder received them), and is
//! checked as such: every joint either at that tick's command or moved toward it by one
//! common step (all leg joints share the URDF limit of 6 rad/s, and one units_per_rad).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
#[path = "../joint_bridge/tests/support/mod.rs"]
mod support;

use std::collections::BTreeMap;
use std::os::unix::process::CommandExt as _;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{bin_dir, python, root};
use joint_bridge::serial::Protocol;
use serde_json::Value;
use support::Board;

/// This test's DDS domain (no other test uses it).
const DOMAIN_ID: u32 = 71;
/// The joint bridge's defaults this test relies on (joint_bridge/src/node/mod.rs).
const RAMP_S: f64 = 2.0;
const RATE_HZ: f64 = 100.0;
/// The URDF speed limit of every leg joint of config/biped.urdf (rad/s).
const LEG_SPEED_RAD_S: f64 = 6.0;
/// One unit on the Dynamixel wire: a tick.
const UNIT: f64 = 1.0;

/// `sh -c SCRIPT` in this test's private network namespace.
fn in_netns(script: &str) -> Command {
    common::in_netns(script, DOMAIN_ID)
}

/// One joint of the calibration file, as this test reads it.
#[derive(Debug, Clone, Copy)]
struct Cal {
    id: u8,
    zero: f64,
    direction: f64,
    units_per_rad: f64,
    min: f64,
    max: f64,
}

impl Cal {
    /// Servo units for a URDF angle: the calibration's mapping, clamped.
    fn units(&self, rad: f64) -> f64 {
        (self.zero + self.direction * self.units_per_rad * rad).clamp(self.min, self.max)
    }
}

fn calibration(path: &Path) -> BTreeMap<String, Cal> {
    let text = std::fs::read_to_string(path).unwrap();
    let y: serde_norway::Value = serde_norway::from_str(&text).unwrap();
    assert_eq!(y["protocol"].as_str(), Some("dynamixel2"));
    let num = |v: &serde_norway::Value, k: &str| {
        v[k].as_f64()
            .or_else(|| v[k].as_i64().map(|i| i as f64))
            .unwrap_or_else(|| panic!("{k} in {v:?}"))
    };
    y["joints"]
        .as_mapping()
        .unwrap()
        .iter()
        .map(|(name, j)| {
            (
                name.as_str().unwrap().to_string(),
                Cal {
                    id: u8::try_from(j["id"].as_u64().unwrap()).unwrap(),
                    zero: num(j, "zero"),
                    direction: num(j, "direction"),
                    units_per_rad: num(j, "units_per_rad"),
                    min: num(j, "min"),
                    max: num(j, "max"),
                },
            )
        })
        .collect()
}

/// A recorded joint command, as bag_check.py decoded it.
#[derive(Debug, Clone)]
struct Recorded {
    /// When the recorder received it.
    t_ns: i64,
    /// Its header stamp (simulated time), s.
    stamp_s: f64,
    names: Vec<String>,
    positions: Vec<f64>,
}

/// Goals by servo id (units).
type Goal = BTreeMap<u8, f64>;

/// What the board should receive for a command: every calibrated joint of it, by servo id.
fn expected(cal: &BTreeMap<String, Cal>, c: &Recorded) -> Goal {
    let g: Goal = c
        .names
        .iter()
        .zip(&c.positions)
        .filter_map(|(n, &a)| cal.get(n).map(|j| (j.id, j.units(a))))
        .collect();
    assert_eq!(
        g.len(),
        cal.len(),
        "a recorded command does not name every leg joint: {c:?}"
    );
    g
}

fn within(got: &Goal, want: &Goal, tol: f64) -> bool {
    got.len() == want.len()
        && got
            .iter()
            .zip(want)
            .all(|((i, g), (j, w))| i == j && (g - w).abs() <= tol)
}

fn worst(got: &Goal, want: &Goal) -> String {
    got.iter()
        .zip(want)
        .map(|((i, g), (_, w))| (i, g, w, (g - w).abs()))
        .max_by(|a, b| a.3.total_cmp(&b.3))
        .map(|(i, g, w, d)| format!("servo {i}: got {g}, want {w} (off by {d:.1})"))
        .unwrap_or_default()
}

/// Whether `goal`, sent after `prev`, is the bridge's velocity limit moving toward `target`:
/// each joint at the target (within a unit) or short of it, moved toward it by one step
/// common to every joint short of it (rounding: within 2 units), and no joint moved more.
/// Returns the step (units).
fn velocity_limited_step(prev: &Goal, goal: &Goal, target: &Goal) -> Option<f64> {
    let mut short = Vec::new();
    let mut reached = Vec::new();
    for (&g, (&p, &t)) in goal.values().zip(prev.values().zip(target.values())) {
        if (g - t).abs() <= UNIT {
            reached.push((g - p).abs());
        } else if (g - p) * (t - p) > 0.0 && (g - p).abs() < (t - p).abs() {
            short.push((g - p).abs());
        } else {
            return None;
        }
    }
    let lo = short.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = short.iter().copied().fold(0.0, f64::max);
    (!short.is_empty() && hi - lo <= 2.0 * UNIT && reached.iter().all(|&r| r <= hi + 2.0 * UNIT))
        .then_some(hi)
}

#[test]
fn replayed_joint_commands_reach_the_serial_board_through_the_calibration() {
    let bins = bin_dir();
    let biped = bins.join("biped");
    let tmp = std::env::temp_dir().join(format!("biped-bag-serial-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(&tmp).unwrap();
    let bag = tmp.join("sim_bag");

    // 1. Record the simulated walk, in real time. The slow walk: at the defaults the timing
    //    search runs the knees up to the servos' 6 rad/s, so every replayed pair of commands
    //    that bunches into one 10 ms period is velocity-limited, and what is checked here
    //    is the commands reaching the board, not the limiter.
    let slow = root().join("tests/data/gait_slow.yaml");
    let t_walk = Instant::now();
    let walk = in_netns("exec \"$@\"")
        .arg(&biped)
        .args([
            "walk",
            "--params",
            slow.to_str().unwrap(),
            "--steps",
            "2",
            "--real-time",
            "--settle",
            "5",
            "--bag",
        ])
        .arg(&bag)
        .arg("--out")
        .arg(tmp.join("walk"))
        .output()
        .expect("unshare runs (root needed for a private network namespace)");
    assert!(
        walk.status.success(),
        "biped walk failed:\n{}\n{}",
        String::from_utf8_lossy(&walk.stdout),
        String::from_utf8_lossy(&walk.stderr)
    );
    let walk_s = t_walk.elapsed().as_secs_f64();

    // 2. The recorded joint commands, read by the independent reader; the bag passes the
    //    strict check.
    let dump = tmp.join("dump.jsonl");
    let check = Command::new(python())
        .arg(root().join("tests/python/bag_check.py"))
        .arg(&bag)
        .arg("--strict")
        .arg("--dump")
        .arg(&dump)
        .output()
        .unwrap();
    let answer: Value = serde_json::from_slice(&check.stdout).unwrap_or_else(|e| {
        panic!(
            "bag_check.py printed no JSON ({e}): {}",
            String::from_utf8_lossy(&check.stderr)
        )
    });
    assert_eq!(
        answer["ok"],
        Value::Bool(true),
        "bag_check.py --strict: {answer:#}"
    );
    assert!(check.status.success(), "{answer:#}");
    assert_eq!(answer["storage"], "mcap");
    let commands: Vec<Recorded> = std::fs::read_to_string(&dump)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<Value>(l).unwrap())
        .filter(|m| m["topic"] == "/joint_commands")
        .map(|m| {
            assert_eq!(m["type"], "sensor_msgs/msg/JointState");
            let f = |v: &Value| match v {
                Value::Number(n) => n.as_f64().unwrap(),
                other => panic!("joint command position {other}"),
            };
            let stamp = &m["msg"]["header"]["stamp"];
            Recorded {
                t_ns: m["t_ns"].as_i64().unwrap(),
                stamp_s: stamp["sec"].as_f64().unwrap() + stamp["nanosec"].as_f64().unwrap() * 1e-9,
                names: m["msg"]["name"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|n| n.as_str().unwrap().to_string())
                    .collect(),
                positions: m["msg"]["position"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(f)
                    .collect(),
            }
        })
        .collect();
    assert_eq!(
        commands.len() as u64,
        answer["topics"]["/joint_commands"]["count"]
            .as_u64()
            .unwrap()
    );
    assert!(
        commands.len() > 1000,
        "{} joint commands recorded",
        commands.len()
    );

    let cal_file = root().join("config/calibration_dynamixel2.yaml");
    let cal = calibration(&cal_file);
    assert_eq!(cal.len(), 10, "the ten leg joints");
    let want: Vec<Goal> = commands.iter().map(|c| expected(&cal, c)).collect();
    // The test's premise: the first recorded pose (standing) lasts beyond the start ramp,
    // so the ramp goes from the measured pose to that pose.
    let first_change = want
        .iter()
        .position(|w| !within(w, &want[0], 0.0))
        .expect("the recorded commands move");
    let standing_s = (commands[first_change].t_ns - commands[0].t_ns) as f64 * 1e-9;
    assert!(
        standing_s > RAMP_S + 0.5,
        "the recorded walk stands only {standing_s:.2} s before moving (< ramp {RAMP_S} s + 0.5 s)"
    );
    let bag_s = (commands[commands.len() - 1].t_ns - commands[0].t_ns) as f64 * 1e-9;

    // 3. The board, its servos crouched (away from the first command: the ramp shows).
    let dir = support::temp_dir("bag-replay");
    let dev = dir.join("ttyBOARD");
    let crouch = |name: &str| match &name[2..] {
        "hip_pitch" | "ankle_pitch" => -0.25,
        "knee" => 0.5,
        _ => 0.1,
    };
    let start: Goal = cal
        .iter()
        .map(|(n, j)| (j.id, j.units(crouch(n)).round()))
        .collect();
    let board = Board::new(
        Protocol::Dynamixel2,
        &dev,
        &start.iter().map(|(&i, &u)| (i, u)).collect::<Vec<_>>(),
    );

    let log = tmp.join("bridge.log");
    let script = r#"
log="$1"; shift
bridge="$1"; shift
biped="$1"; shift
bag="$1"; shift
"$bridge" --ros-args "$@" >"$log" 2>&1 &
jb=$!
n=0
until grep -q "ready:" "$log"; do
  kill -0 $jb 2>/dev/null || { echo "joint_bridge exited before it was ready" >&2; exit 91; }
  n=$((n+1)); [ $n -gt 1200 ] && { echo "joint_bridge not ready after 60 s" >&2; kill -INT $jb; exit 92; }
  sleep 0.05
done
"$biped" replay "$bag" --topics /joint_commands --wait-for-subscribers 10
rc=$?
# The watchdog holds the last pose; then stop the bridge as Ctrl-C would.
sleep 1
kill -INT $jb
wait $jb
jrc=$?
echo "replay exit $rc, joint_bridge exit $jrc" >&2
[ $rc -eq 0 ] && [ $jrc -eq 0 ]
"#;
    let mut child = in_netns(script)
        .arg(&log)
        .arg(bins.join("joint_bridge"))
        .arg(&biped)
        .arg(&bag)
        .args(["-p", "backend:=serial", "-p", "protocol:=dynamixel2"])
        .arg("-p")
        .arg(format!("port:={}", dev.display()))
        .args(["-p", "baud:=1000000", "-p"])
        .arg(format!("calibration_file:={}", cal_file.display()))
        // What this test follows is each recorded command through the calibration to the
        // board, packet for packet, with the velocity limit. The bridge's acceleration limit
        // (joint_bridge/tests/no_snap.rs tests it) would smooth the replay's timing jitter
        // into goals between recorded commands, so it is set out of the way here.
        .args(["-p", "acceleration_limit_rad_s2:=100000"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .process_group(0)
        .spawn()
        .expect("unshare runs");
    // Watch the board while it runs: when each goal packet came, and what the board had
    // been told when the first came.
    let t_replay = Instant::now();
    let mut arrivals: Vec<f64> = Vec::new();
    let mut at_first_goal: Option<Vec<String>> = None;
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t_replay.elapsed() > Duration::from_secs(180) {
            let _ = nix::sys::signal::killpg(
                nix::unistd::Pid::from_raw(child.id() as i32),
                nix::sys::signal::Signal::SIGKILL,
            );
            let _ = child.wait();
            panic!(
                "the replay did not end within 180 s; bridge log:\n{}",
                std::fs::read_to_string(&log).unwrap_or_default()
            );
        }
        let (n, cmds) = board.with(|s| (s.goals.len(), s.commands.clone()));
        if n > 0 && at_first_goal.is_none() {
            at_first_goal = Some(cmds);
        }
        let now = t_replay.elapsed().as_secs_f64();
        arrivals.resize(n, now);
        std::thread::sleep(Duration::from_millis(2));
    };
    let out = child.wait_with_output().unwrap();
    let bridge_log = std::fs::read_to_string(&log).unwrap_or_default();
    let replay_s = t_replay.elapsed().as_secs_f64();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        status.success(),
        "replay into the serial bridge failed ({status}):\n{stderr}\nbridge log:\n{bridge_log}"
    );
    assert!(
        stderr.contains(&format!("{} messages on", answer["message_count"])),
        "{stderr}"
    );
    assert!(
        bridge_log.contains("ready: backend dynamixel2 on") && bridge_log.contains(" active,"),
        "{bridge_log}"
    );
    for bad in [
        "backend failed",
        "still failing",
        "configured and active again",
        "[ERROR]",
    ] {
        assert!(
            !bridge_log.contains(bad),
            "bridge log has `{bad}`:\n{bridge_log}"
        );
    }
    assert!(
        bridge_log.contains("shutting down: torque off"),
        "{bridge_log}"
    );

    // 4. What the board received.
    let (goals, cmds, servos) = board.with(|s| {
        (
            s.goals
                .iter()
                .map(|g| g.iter().copied().collect::<Goal>())
                .collect::<Vec<_>>(),
            s.commands.clone(),
            s.servos.clone(),
        )
    });
    drop(board);
    // Kept for a look when an assertion fails (the folder is removed on success).
    std::fs::write(
        tmp.join("goals.json"),
        serde_json::to_string(&serde_json::json!({
            "goals": goals.iter().map(|g| g.values().copied().collect::<Vec<_>>()).collect::<Vec<_>>(),
            "arrivals_s": arrivals,
            "start": start.values().copied().collect::<Vec<_>>(),
        }))
        .unwrap(),
    )
    .unwrap();
    let ids: Vec<u8> = cal.values().map(|j| j.id).collect();
    assert!(goals.len() > 500, "{} goal packets", goals.len());
    for (k, g) in goals.iter().enumerate() {
        assert_eq!(
            g.keys().copied().collect::<Vec<_>>(),
            {
                let mut i = ids.clone();
                i.sort_unstable();
                i
            },
            "packet {k}: every leg servo, once"
        );
        // Never beyond the calibration's limits.
        for j in cal.values() {
            let u = g[&j.id];
            assert!(
                (j.min..=j.max).contains(&u),
                "packet {k}: servo {} goal {u} outside [{}, {}]",
                j.id,
                j.min,
                j.max
            );
        }
    }

    // Torque: on for every servo before the first goal, off for every one at the end, and
    // on only once (no reconnection, no limp).
    let first = at_first_goal.expect("a goal packet was seen");
    for id in &ids {
        assert!(first.contains(&format!("torque {id} 1")), "{first:?}");
        assert!(!first.contains(&format!("torque {id} 0")), "{first:?}");
        assert_eq!(
            cmds.iter()
                .filter(|c| **c == format!("torque {id} 1"))
                .count(),
            1,
            "{cmds:?}"
        );
        let last_on = cmds
            .iter()
            .rposition(|c| *c == format!("torque {id} 1"))
            .unwrap();
        assert!(
            cmds[last_on..].contains(&format!("torque {id} 0")),
            "servo {id} not torqued off at the end: {cmds:?}"
        );
    }
    assert!(servos.values().all(|s| !s.torque), "{servos:?}");

    // The start: the measured pose held until the first command, then a smooth ramp to the
    // first recorded pose, never beyond it, never a jump.
    assert!(
        within(&goals[0], &start, UNIT),
        "first packet is not the measured pose: {}",
        worst(&goals[0], &start)
    );
    let ramp_end = goals
        .iter()
        .position(|g| within(g, &want[0], UNIT))
        .expect("the ramp reaches the first recorded pose");
    let ramp_start = goals.iter().position(|g| !within(g, &start, UNIT)).unwrap();
    assert!(ramp_start < ramp_end);
    let span: f64 = start
        .iter()
        .map(|(i, s)| (s - want[0][i]).abs())
        .fold(0.0, f64::max);
    for (k, pair) in goals[..=ramp_end].windows(2).enumerate() {
        for (id, &u) in &pair[1] {
            let (a, b) = (start[id], want[0][id]);
            assert!(
                u >= a.min(b) - UNIT && u <= a.max(b) + UNIT,
                "ramp packet {}: servo {id} at {u}, outside [{a}, {b}]",
                k + 1
            );
            // No jump: the smoothstep's steepest slope is 1.5 × span / ramp, so a quarter
            // of the span takes 1/3 s; packets come every 10 ms.
            let step = (u - pair[0][id]).abs();
            assert!(
                step <= span / 4.0,
                "ramp packet {}: servo {id} jumped {step} units",
                k + 1
            );
        }
    }
    let ramp_s = arrivals[ramp_end] - arrivals[ramp_start];
    assert!(
        (0.7 * RAMP_S..=1.3 * RAMP_S).contains(&ramp_s),
        "the ramp took {ramp_s:.2} s ({} packets), not about {RAMP_S} s",
        ramp_end - ramp_start
    );

    // After the ramp: every goal is a recorded command through the calibration, in the
    // recorded order (repeats and skips allowed), or a velocity-limited step toward the
    // next; `at` is the latest command reached.
    let mut at = 0usize;
    let mut limited: Vec<(usize, f64)> = Vec::new();
    for k in ramp_end..goals.len() {
        let g = &goals[k];
        if let Some(i) = (at..want.len()).find(|&i| within(g, &want[i], UNIT)) {
            at = i;
            continue;
        }
        let explained = (at..want.len())
            .find_map(|i| velocity_limited_step(&goals[k - 1], g, &want[i]).map(|s| (i, s)));
        match explained {
            Some((i, step)) => {
                at = i;
                limited.push((k, step));
            }
            None => {
                let near = (0..want.len())
                    .min_by(|&a, &b| {
                        let d = |i: usize| {
                            g.iter()
                                .map(|(id, u)| (u - want[i][id]).abs())
                                .fold(0.0, f64::max)
                        };
                        d(a).total_cmp(&d(b))
                    })
                    .unwrap();
                panic!(
                    "goal packet {k} (of {}) is no recorded command from #{at} on, nor a \
                     velocity-limited step toward one: nearest is #{near}: {}; previous packet \
                     {:?}, packet {g:?}, command #{at} {:?}",
                    goals.len(),
                    worst(g, &want[near]),
                    goals[k - 1],
                    want[at]
                );
            }
        }
    }
    // The last goal is the last recorded command (the watchdog then held it).
    let last = goals.last().unwrap();
    assert!(
        within(last, want.last().unwrap(), UNIT),
        "last goal is not the last recorded command: {}",
        worst(last, want.last().unwrap())
    );
    // Most recorded commands reached the board. Counted in poses (a run of identical
    // commands is one pose), a pose seen when some goal after the ramp is within a unit of
    // it. The bridge takes the newest command once per period (10 ms), so a pose the
    // recording held for h < 10 ms is seen with a chance of about h / 10 ms: the expected
    // fraction. That chance is not independent from pose to pose: the replay and the bridge
    // both run at 100 Hz on the wall clock, with a phase between them fixed for the run.
    // When the bridge's period falls near the instants the replay sends, each period takes
    // one of two neighbouring poses at the whim of either side's jitter, and about one pose
    // in four is skipped: 991 of 1179 expected (0.84) was seen so on a busy 2-core machine.
    // So the floor is 0.6 of the expectation, which a bridge taking every other command
    // (0.5) or a replay losing messages still fails; the replay's millisecond timing is
    // `cargo bench --bench bag_replay`'s. A pose held for a period or more should almost
    // always be seen, whatever the phase.
    let post_ramp = &goals[ramp_end..];
    let mut poses = Vec::new(); // (held for, seen)
    let mut i = 0;
    while i < want.len() {
        let j = (i..want.len())
            .find(|&j| !within(&want[j], &want[i], 0.0))
            .unwrap_or(want.len());
        let held_s = commands
            .get(j)
            .map_or(f64::INFINITY, |c| (c.t_ns - commands[i].t_ns) as f64 * 1e-9);
        let seen = post_ramp.iter().any(|g| within(g, &want[i], UNIT));
        poses.push((held_s, seen));
        i = j;
    }
    let count = |min_held_s: f64| {
        let p: Vec<bool> = poses
            .iter()
            .filter(|p| p.0 >= min_held_s)
            .map(|p| p.1)
            .collect();
        (p.iter().filter(|&&s| s).count(), p.len())
    };
    let (all_seen, all) = count(0.0);
    let (held_seen, held) = count(1.0 / RATE_HZ);
    let expected: f64 = poses.iter().map(|p| (p.0 * RATE_HZ).min(1.0)).sum();
    let sim_s = commands[commands.len() - 1].stamp_s - commands[0].stamp_s;
    let limit_per_tick = LEG_SPEED_RAD_S / RATE_HZ * cal.values().next().unwrap().units_per_rad;
    eprintln!(
        "walk recorded in {walk_s:.1} s: {} joint commands, {sim_s:.1} s of simulated time \
         over {bag_s:.1} s; replay + bridge {replay_s:.1} s: {} goal packets, ramp {ramp_s:.2} s \
         ({} packets); recorded poses seen: {all_seen} of {all} (a 100 Hz sampler expects \
         {expected:.0}), of those held ≥ 10 ms {held_seen} of {held}; {} velocity-limited \
         packets (steps {:?} units; the limit is {limit_per_tick:.0} units per 10 ms)",
        commands.len(),
        goals.len(),
        ramp_end - ramp_start,
        limited.len(),
        limited.iter().map(|l| l.1.round()).collect::<Vec<_>>()
    );
    assert!(
        all_seen as f64 >= 0.6 * expected,
        "only {all_seen} of {all} recorded poses reached the board (a 100 Hz sampler of the \
         recorded timing sees {expected:.0})"
    );
    assert!(
        held_seen as f64 >= 0.9 * held as f64,
        "only {held_seen} of {held} recorded poses held ≥ 10 ms reached the board"
    );
    // Velocity-limited packets: only where the replayed commands came faster than the legs
    // may move, i.e. rarely in a walk recorded in real time.
    assert!(
        limited.len() * 50 <= goals.len() - ramp_end,
        "{} of {} packets after the ramp were velocity-limited: {limited:?}",
        limited.len(),
        goals.len() - ramp_end
    );
    let _ = std::fs::remove_dir_all(&tmp);
    let _ = std::fs::remove_dir_all(&dir);
}
