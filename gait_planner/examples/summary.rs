//! Prints a phase-by-phase summary of a default walk: `cargo run -p gait_planner --example summary -- [STEPS]`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
fn main() {
    let steps = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let model = ik_solver::BipedModel::from_urdf_str(ik_solver::DEFAULT_URDF, None).unwrap();
    let mut planner =
        match gait_planner::GaitPlanner::new(model, gait_planner::GaitParams::default()) {
            Ok(p) => p,
            Err(e) => return println!("refused: {e}"),
        };
    println!("{:?}", planner.config());
    let samples = planner
        .plan(gait_planner::WalkRequest::Steps(steps))
        .unwrap();
    let mut last = None;
    let mut min_margin = f64::INFINITY;
    for s in &samples {
        min_margin = min_margin.min(s.margin_m);
        if last != Some((s.phase, s.step_index)) {
            println!(
                "t={:6.2} {:16} {:7} step {} base ({:+.4},{:+.4},{:.4}) com ({:+.4},{:+.4}) margin {:.4} issues {}",
                s.t_s,
                s.phase.as_str(),
                s.support.as_str(),
                s.step_index,
                s.base_world.translation.x,
                s.base_world.translation.y,
                s.base_world.translation.z,
                s.com_world_m.x,
                s.com_world_m.y,
                s.margin_m,
                s.issues.len()
            );
            last = Some((s.phase, s.step_index));
        }
    }
    let e = samples.last().unwrap();
    println!(
        "end t={:.2} base ({:+.4},{:+.4}) feet L {:?} R {:?} min margin {min_margin:.4}",
        e.t_s,
        e.base_world.translation.x,
        e.base_world.translation.y,
        e.ankles_world_m[0].coords.as_slice(),
        e.ankles_world_m[1].coords.as_slice()
    );
}
