//! What the planner gives a viewer for each tick (`GaitPlanner::balance_view`, drawn as
//! RViz markers by the node): the support polygon of the feet down, the CoM over it, and
//! during a swing the foot's landing, which is where the foot is once the swing is over.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;
use common::*;
use gait_planner::{GaitParams, GaitPlanner, Stride, Support, WalkRequest};
use ik_solver::{BipedModel, Side};

fn walk_and_check(model: BipedModel, stride: Option<Stride>) {
    let mut planner = GaitPlanner::new(model.clone(), GaitParams::slow(&model)).unwrap();
    if let Some(stride) = stride {
        planner.set_stride(stride).unwrap();
    }
    planner.request(WalkRequest::Steps(3));
    let dt = 1.0 / planner.config().control_rate_hz;
    let mut ticks = Vec::new();
    let mut k = 0;
    loop {
        let s = planner.update(k as f64 * dt).unwrap();
        let view = planner.balance_view(&s);
        let idle = planner.is_idle();
        ticks.push((s, view));
        k += 1;
        if idle && k > 10 {
            break;
        }
    }
    let mut swings = 0;
    for (i, (s, view)) in ticks.iter().enumerate() {
        assert_eq!(view.margin_m, s.margin_m);
        assert_eq!(view.com_xy, [s.com_world_m.x, s.com_world_m.y]);
        assert!(
            view.margin_m >= view.min_margin_m,
            "tick {i}: {}",
            view.margin_m
        );
        match s.support {
            Support::Left | Support::Right => {
                // One foot down: the polygon is its sole, as the model's sole rectangle
                // placed at that ankle and heading.
                let down = if s.support == Support::Left {
                    Side::Left
                } else {
                    Side::Right
                };
                let a = s.ankles_world_m[down.index()];
                let sole = model
                    .leg(down)
                    .sole
                    .corners([a.x, a.y], s.feet_yaw_rad[down.index()]);
                assert_eq!(view.support_polygon, sole.to_vec(), "tick {i}");
                // The foot in the air lands where it is at the first tick after the swing.
                let up = down.other();
                assert_eq!(view.footsteps.len(), 1, "tick {i}");
                assert_eq!(view.footsteps[0].0, up);
                let after = ticks[i..]
                    .iter()
                    .find(|(t, _)| t.phase != s.phase)
                    .map(|(t, _)| t)
                    .unwrap();
                let a = after.ankles_world_m[up.index()];
                let landed = model
                    .leg(up)
                    .sole
                    .corners([a.x, a.y], after.feet_yaw_rad[up.index()]);
                for (g, w) in view.footsteps[0].1.iter().zip(&landed) {
                    assert!((g[0] - w[0]).abs() < 1e-12 && (g[1] - w[1]).abs() < 1e-12);
                }
                swings += 1;
            }
            Support::Double => {
                // Both soles: 4 to 8 corners, counter-clockwise.
                let n = view.support_polygon.len();
                assert!((4..=8).contains(&n), "tick {i}: {n} corners");
                assert!(view.footsteps.is_empty(), "tick {i}");
            }
        }
    }
    assert!(swings > 100, "{swings} swing ticks");
}

#[test]
fn the_default_robot_walking_forward() {
    walk_and_check(default_model(), None);
}

#[test]
fn the_six_joint_robot_turning_sideways() {
    walk_and_check(
        biped6_model(),
        Some(Stride {
            forward_m: 0.01,
            left_m: 0.005,
            turn_rad: 0.05,
        }),
    );
}
