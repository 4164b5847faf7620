//! `biped plan`: a walk planned offline, written as CSV (one row per control tick) plus
//! pictures.
//!
//! The CSV is a contract that other tools read. Header, in this order:
//! `t,phase,support,base_x,base_y,base_z,base_yaw,l_ankle_x,l_ankle_y,l_ankle_z,r_ankle_x,
//! r_ankle_y,r_ankle_z,com_x,com_y,com_z,margin`, then one column per movable joint named by
//! its URDF joint name (URDF order), in radians. Numbers are written with Rust's shortest
//! round-trip formatting, so a reader gets back exactly the planned `f64`s.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::Context;
use gait_planner::GaitSample;
use ik_solver::RobotModel;

/// The fixed first columns of the plan CSV.
pub const CSV_COLUMNS: [&str; 17] = [
    "t",
    "phase",
    "support",
    "base_x",
    "base_y",
    "base_z",
    "base_yaw",
    "l_ankle_x",
    "l_ankle_y",
    "l_ankle_z",
    "r_ankle_x",
    "r_ankle_y",
    "r_ankle_z",
    "com_x",
    "com_y",
    "com_z",
    "margin",
];

/// Writes the plan CSV.
pub fn write_csv(
    out: &mut impl Write,
    robot: &RobotModel,
    samples: &[GaitSample],
) -> std::io::Result<()> {
    let mut header: Vec<&str> = CSV_COLUMNS.to_vec();
    header.extend(robot.dof_names());
    writeln!(out, "{}", header.join(","))?;
    for s in samples {
        let b = &s.base_world.translation;
        let (_, _, yaw) = s.base_world.rotation.euler_angles();
        let [l, r] = &s.ankles_world_m;
        let c = &s.com_world_m;
        write!(out, "{},{},{}", s.t_s, s.phase, s.support)?;
        for v in [
            b.x, b.y, b.z, yaw, l.x, l.y, l.z, r.x, r.y, r.z, c.x, c.y, c.z, s.margin_m,
        ] {
            write!(out, ",{}", v + 0.0)?; // + 0.0 writes -0 as 0
        }
        for v in &s.joints_rad {
            write!(out, ",{}", v + 0.0)?;
        }
        writeln!(out)?;
    }
    Ok(())
}

/// Writes the CSV to a file, creating its folder.
pub fn write_csv_file(
    path: &Path,
    robot: &RobotModel,
    samples: &[GaitSample],
) -> anyhow::Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create folder {}", dir.display()))?;
    }
    let file =
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let mut out = std::io::BufWriter::new(file);
    write_csv(&mut out, robot, samples)
        .and_then(|_| out.flush())
        .with_context(|| format!("cannot write {}", path.display()))
}

/// What a plan covered, for the summary line.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanSummary {
    /// Ticks.
    pub rows: usize,
    /// Duration (s).
    pub duration_s: f64,
    /// Forward distance of the base from the first to the last tick (m).
    pub distance_m: f64,
    /// Leftward distance of the base from the first to the last tick (m).
    pub left_m: f64,
    /// Smallest CoM margin (m).
    pub min_margin_m: f64,
    /// Smallest margin of the planned (cart-table) ZMP (m).
    pub min_zmp_margin_m: f64,
    /// Files written.
    pub files: Vec<PathBuf>,
}

impl PlanSummary {
    /// Sums up samples.
    pub fn of(samples: &[GaitSample]) -> Self {
        let (first, last) = (samples.first(), samples.last());
        Self {
            rows: samples.len(),
            duration_s: last.map(|s| s.t_s).unwrap_or(0.0) - first.map(|s| s.t_s).unwrap_or(0.0),
            distance_m: match (first, last) {
                (Some(a), Some(b)) => b.base_world.translation.x - a.base_world.translation.x,
                _ => 0.0,
            },
            left_m: match (first, last) {
                (Some(a), Some(b)) => b.base_world.translation.y - a.base_world.translation.y,
                _ => 0.0,
            },
            min_margin_m: samples
                .iter()
                .map(|s| s.margin_m)
                .fold(f64::INFINITY, f64::min),
            min_zmp_margin_m: samples
                .iter()
                .map(|s| s.zmp_margin_m)
                .fold(f64::INFINITY, f64::min),
            files: Vec::new(),
        }
    }
}

/// Parses `--twist vx,vy,wz`: three finite numbers, m/s forward, m/s left, rad/s
/// counter-clockwise.
pub fn parse_twist(text: &str) -> Result<gait_planner::Velocity, String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let [x, y, z] = parts.as_slice() else {
        return Err(format!(
            "`{text}`: expected three numbers vx,vy,wz (m/s, m/s, rad/s)"
        ));
    };
    let num = |name: &str, v: &str| -> Result<f64, String> {
        match v.parse::<f64>() {
            Ok(n) if n.is_finite() => Ok(n),
            _ => Err(format!("{name} = `{v}` is not a finite number")),
        }
    };
    Ok(gait_planner::Velocity {
        x_m_s: num("vx", x)?,
        y_m_s: num("vy", y)?,
        yaw_rad_s: num("wz", z)?,
    })
}

/// Sets the planner's stride from `--twist` as the planner node does with a command's
/// velocity: scaled into the step limits, with a warning on stderr when it was.
pub fn apply_twist(
    planner: &mut gait_planner::GaitPlanner,
    v: gait_planner::Velocity,
) -> anyhow::Result<()> {
    let cmd = planner.stride_for(v).context("--twist")?;
    if let Some(l) = cmd.limited_to {
        eprintln!(
            "biped: warning: --twist {},{},{} is beyond the step limits; walking {:.4},{:.4},{:.4}",
            v.x_m_s, v.y_m_s, v.yaw_rad_s, l.x_m_s, l.y_m_s, l.yaw_rad_s
        );
    }
    let taken = planner.set_stride(cmd.stride).context("--twist")?;
    if taken != cmd.stride {
        eprintln!(
            "biped: warning: --twist: the first step at that velocity fails its check; walking {:.4} m, {:.4} m, {:.4} rad per step",
            taken.forward_m, taken.left_m, taken.turn_rad
        );
    }
    Ok(())
}
