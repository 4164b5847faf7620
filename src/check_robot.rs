//! `biped check-robot`: a newcomer's first command with their own robot. It reads the URDF
//! (with a leg map if given) as the fleet will, says what it found and what the gait will do
//! with it, tries a short plan and, with a scene, the simulator; it lists every problem, not
//! just the first, and draws the legs as an SVG (front and side views, joint axes marked).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use gait_planner::{GaitParams, GaitPlanner, WalkRequest};
use ik_solver::{Axis, BipedModel, JointRole, LegRoleMap, Side};
use nalgebra::{Isometry3, Vector3};
use sim_bridge::{JointMap, Sim, SimConfig};

/// Steps of the trial plan: the first half step, a full step each side, the closing half step.
const TRIAL_STEPS: u32 = 2;

/// What to check.
#[derive(Debug, Clone)]
pub struct CheckRequest {
    /// The robot's URDF.
    pub urdf: PathBuf,
    /// Leg joints named explicitly, if the axes do not tell.
    pub leg_map: Option<LegRoleMap>,
    /// A MuJoCo scene of the robot and its joint map to the URDF's names.
    pub scene: Option<(PathBuf, PathBuf)>,
    /// Gait parameters (defaults: 0 = derived from the robot).
    pub params: GaitParams,
    /// Where to draw the legs.
    pub svg: PathBuf,
}

/// What was found: the report (lines for the user) and every problem.
#[derive(Debug, Default)]
pub struct CheckOutcome {
    /// What was found, in reading order.
    pub report: String,
    /// Every problem found; empty when the robot is ready to plan and walk.
    pub problems: Vec<String>,
}

/// Checks a robot as the fleet would read it. Only a failure to write the drawing is an
/// error; everything about the robot is in the outcome.
pub fn check(req: &CheckRequest) -> anyhow::Result<CheckOutcome> {
    let mut out = CheckOutcome::default();
    let text = match std::fs::read_to_string(&req.urdf) {
        Ok(t) => t,
        Err(e) => {
            out.problems
                .push(format!("cannot read {}: {e}", req.urdf.display()));
            return Ok(out);
        }
    };
    let model = match BipedModel::from_urdf_str_all(&text, req.leg_map.as_ref()) {
        Ok(m) => m,
        Err(problems) => {
            out.problems.extend(
                problems
                    .iter()
                    .map(|p| format!("{}: {p}", req.urdf.display())),
            );
            return Ok(out);
        }
    };
    describe(&mut out.report, &model, &req.urdf);

    // Durations left at 0 (auto) searched once, for the defaults printed and the trial plan.
    let params = req.params.with_auto_timing(&model).map(|(p, _)| p);
    match params.clone().and_then(|p| p.resolve(&model)) {
        Ok(p) => {
            let _ = writeln!(
                out.report,
                "gait defaults for this robot: step {:.3} m in {:.2} s, foot lift {:.3} m, hip height {:.3} m, shift {:.2} s, {} Hz, CoM margin at least {:.4} m",
                p.step_length_m,
                p.step_duration_s,
                p.foot_lift_m,
                p.hip_height_m,
                p.shift_duration_s,
                p.control_rate_hz,
                p.min_com_margin_m
            );
        }
        Err(e) => out.problems.push(format!("gait parameters: {e}")),
    }
    match params
        .and_then(|p| GaitPlanner::new(model.clone(), p))
        .and_then(|mut p| p.plan(WalkRequest::Steps(TRIAL_STEPS)))
    {
        Ok(samples) => {
            let worst = samples
                .iter()
                .map(|s| s.margin_m)
                .fold(f64::INFINITY, f64::min);
            let _ = writeln!(
                out.report,
                "a {TRIAL_STEPS}-step plan passes the stability check: smallest CoM margin {worst:.4} m"
            );
        }
        Err(e) => out.problems.push(format!("a {TRIAL_STEPS}-step plan: {e}")),
    }
    if let Some((scene, map)) = &req.scene {
        check_scene(&mut out, &model, &text, req.leg_map.as_ref(), scene, map);
    }
    std::fs::write(&req.svg, draw_legs(&model))
        .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", req.svg.display()))?;
    let _ = writeln!(out.report, "drew the legs: {}", req.svg.display());
    Ok(out)
}

fn check_scene(
    out: &mut CheckOutcome,
    model: &BipedModel,
    urdf: &str,
    leg_map: Option<&LegRoleMap>,
    scene: &Path,
    map: &Path,
) {
    let joint_map = match JointMap::from_yaml_file(map) {
        Ok(m) => m,
        Err(e) => {
            out.problems
                .push(format!("joint map {}: {e}", map.display()));
            return;
        }
    };
    match Sim::from_mjcf_file(scene, &joint_map, urdf, leg_map, &SimConfig::default()) {
        Ok(sim) => {
            let urdf_mass = model.robot().total_mass_kg();
            let _ = writeln!(
                out.report,
                "scene {} with map {}: accepted, {} joints driven, {:.3} kg (URDF {:.3} kg), servos kp {} N*m/rad",
                scene.display(),
                map.display(),
                sim.joint_names().len(),
                sim.total_mass_kg(),
                urdf_mass,
                sim.config().kp_nm_per_rad
            );
        }
        Err(e) => out.problems.push(format!("scene {}: {e}", scene.display())),
    }
}

fn axis_text(role: JointRole, sign: f64) -> String {
    let a = match role.axis() {
        Axis::X => "x",
        Axis::Y => "y",
        Axis::Z => "z",
    };
    format!("{}{a}", if sign < 0.0 { "-" } else { "+" })
}

fn describe(out: &mut String, model: &BipedModel, path: &Path) {
    let robot = model.robot();
    let q = vec![0.0; robot.dof_count()];
    let poses = robot
        .link_poses(&Isometry3::identity(), &q)
        .unwrap_or_default();
    let mass = robot.total_mass_kg();
    let com = robot.center_of_mass(&poses);
    let _ = writeln!(
        out,
        "robot `{}` ({}): {} links, {} movable joints, {mass:.3} kg, centre of mass at zero angles ({:.4}, {:.4}, {:.4}) m from `{}`",
        robot.name(),
        path.display(),
        robot.links().len(),
        robot.dof_count(),
        com.x,
        com.y,
        com.z,
        robot.links()[robot.root()].name
    );
    for side in Side::BOTH {
        let leg = model.leg(side);
        let _ = writeln!(out, "{side} leg, {} joints:", leg.present().count());
        for (role, j) in leg.present() {
            let _ = writeln!(
                out,
                "  {:<12} {:<24} axis {}  limits [{:.3}, {:.3}] rad",
                role.to_string(),
                format!("`{}`", j.name),
                axis_text(role, j.axis_sign),
                j.limits.lower,
                j.limits.upper
            );
        }
        let h = leg.hip_in_base_m;
        let _ = writeln!(
            out,
            "  hip point ({:.4}, {:.4}, {:.4}) m; thigh {:.4} m, shin {:.4} m (tilted {:.2} and {:.2} deg at zero angles)",
            h.x,
            h.y,
            h.z,
            leg.thigh_m,
            leg.shin_m,
            leg.thigh_angle0_rad.to_degrees(),
            leg.shin_angle0_rad.to_degrees()
        );
        let _ = writeln!(
            out,
            "  offsets: ankle point sideways of the hip point e = {:.4} m, hip pitch axis ahead a_h = {:.4} m and below the roll axis h_h = {:.4} m; ankle point to sole {:.4} m",
            leg.ankle_lateral_m,
            leg.hip_pitch_forward_m,
            leg.hip_roll_to_pitch_m,
            leg.ankle_to_sole_m
        );
        let r = &leg.sole;
        let _ = writeln!(
            out,
            "  sole {:.3} x {:.3} m: x [{:.4}, {:.4}], y [{:.4}, {:.4}] m around the ankle point",
            r.length_m(),
            r.width_m(),
            r.x_min_m,
            r.x_max_m,
            r.y_min_m,
            r.y_max_m
        );
    }
}

/// A point of a view: (across, up) in metres.
type ViewPoint = [f64; 2];

/// A view of the legs: its title, how it sees a point, and the base axis across it (index).
struct View {
    title: &'static str,
    project: fn(&Vector3<f64>) -> ViewPoint,
    across: usize,
}

/// One leg at zero angles as a view sees it.
struct LegDrawing {
    /// Joint origins, hip to foot, with the axis of each (base frame).
    joints: Vec<(Vector3<f64>, Vector3<f64>)>,
    hip: Vector3<f64>,
    ankle: Vector3<f64>,
    /// Sole corners (base frame, at the sole's height).
    sole: [Vector3<f64>; 4],
}

fn leg_drawings(model: &BipedModel) -> Vec<LegDrawing> {
    let robot = model.robot();
    let q = vec![0.0; robot.dof_count()];
    let poses = robot
        .link_poses(&Isometry3::identity(), &q)
        .unwrap_or_default();
    Side::BOTH
        .into_iter()
        .map(|side| {
            let leg = model.leg(side);
            let joints = leg
                .present()
                .map(|(_, j)| {
                    let f = robot.joint_frame(&poses, j.joint);
                    (
                        f.translation.vector,
                        f.rotation * robot.joints()[j.joint].axis.into_inner(),
                    )
                })
                .collect();
            let ankle = leg.ankle_world(robot, &poses).coords;
            let z = ankle.z - leg.ankle_to_sole_m;
            let sole = leg
                .sole
                .corners([ankle.x, ankle.y], 0.0)
                .map(|[x, y]| Vector3::new(x, y, z));
            LegDrawing {
                joints,
                hip: leg.hip_in_base_m,
                ankle,
                sole,
            }
        })
        .collect()
}

/// The SVG of the legs: a front view (the robot's left on the right) and a side view (seen
/// from its left, forward to the right). Pitch axes are rings in the side view, roll axes
/// rings in the front view; an axis in the drawing's plane is a short line. H and A, the
/// hip and ankle points of the closed form, are marked.
pub fn draw_legs(model: &BipedModel) -> String {
    const W: f64 = 360.0;
    const H: f64 = 440.0;
    const PAD: f64 = 30.0;
    let legs = leg_drawings(model);
    let views = [
        View {
            title: "front (robot's left on the right)",
            project: |v| [v.y, v.z],
            across: 0,
        },
        View {
            title: "side (seen from the left, forward to the right)",
            project: |v| [v.x, v.z],
            across: 1,
        },
    ];
    let all: Vec<&Vector3<f64>> = legs
        .iter()
        .flat_map(|l| {
            l.joints
                .iter()
                .map(|(p, _)| p)
                .chain(&l.sole)
                .chain([&l.hip])
        })
        .collect();
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n<text x=\"{PAD}\" y=\"18\">{}: legs at zero angles; rings: axes across the view; H hip point, A ankle point</text>\n",
        2.0 * W,
        H + 20.0,
        xml_escape(model.robot().name())
    );
    for (k, view) in views.iter().enumerate() {
        let (title, project, ring_axis) = (view.title, view.project, view.across);
        let pts: Vec<ViewPoint> = all.iter().map(|v| project(v)).collect();
        let (lo, hi) = pts.iter().fold(
            ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]),
            |(lo, hi), p| {
                (
                    [lo[0].min(p[0]), lo[1].min(p[1])],
                    [hi[0].max(p[0]), hi[1].max(p[1])],
                )
            },
        );
        let span = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-3);
        let scale = (W - 2.0 * PAD).min(H - 2.0 * PAD - 30.0) / span;
        let x0 = k as f64 * W + PAD;
        let to_px = |p: ViewPoint| [x0 + (p[0] - lo[0]) * scale, 40.0 + (hi[1] - p[1]) * scale];
        let _ = writeln!(
            svg,
            "<g class=\"view\"><text x=\"{x0}\" y=\"{}\">{title}</text>",
            H + 10.0
        );
        for (li, leg) in legs.iter().enumerate() {
            let colour = if li == 0 { "#1f77b4" } else { "#d62728" };
            let path: Vec<String> = leg
                .joints
                .iter()
                .map(|(p, _)| to_px(project(p)))
                .chain([to_px(project(&leg.ankle))])
                .map(|[x, y]| format!("{x:.1},{y:.1}"))
                .collect();
            let _ = writeln!(
                svg,
                "<polyline class=\"leg\" points=\"{}\" fill=\"none\" stroke=\"{colour}\" stroke-width=\"2\"/>",
                path.join(" ")
            );
            let sole: Vec<String> = leg
                .sole
                .iter()
                .map(|c| to_px(project(c)))
                .map(|[x, y]| format!("{x:.1},{y:.1}"))
                .collect();
            let _ = writeln!(
                svg,
                "<polygon class=\"sole\" points=\"{}\" fill=\"none\" stroke=\"{colour}\"/>",
                sole.join(" ")
            );
            for (p, axis) in &leg.joints {
                let [x, y] = to_px(project(p));
                if axis[ring_axis].abs() > 0.9 {
                    let _ = writeln!(
                        svg,
                        "<circle class=\"axis-across\" cx=\"{x:.1}\" cy=\"{y:.1}\" r=\"5\" fill=\"white\" stroke=\"black\"/>"
                    );
                } else {
                    let [u, v] = project(axis);
                    let _ = writeln!(
                        svg,
                        "<line class=\"axis-along\" x1=\"{:.1}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\" stroke=\"black\"/>",
                        x - 10.0 * u,
                        y + 10.0 * v,
                        x + 10.0 * u,
                        y - 10.0 * v
                    );
                }
            }
            for (label, p) in [("H", &leg.hip), ("A", &leg.ankle)] {
                let [x, y] = to_px(project(p));
                let _ = writeln!(
                    svg,
                    "<rect class=\"point\" x=\"{:.1}\" y=\"{:.1}\" width=\"4\" height=\"4\" fill=\"{colour}\"/><text x=\"{:.1}\" y=\"{:.1}\" font-size=\"11\" fill=\"{colour}\">{label}</text>",
                    x - 2.0,
                    y - 2.0,
                    x - 16.0,
                    y + 4.0
                );
            }
        }
        svg.push_str("</g>\n");
    }
    svg.push_str("</svg>\n");
    svg
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}
