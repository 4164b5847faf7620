//! The pictures of a simulated walk, written by `biped walk` next to `report.json`:
//!
//! - `walk_top_view.svg`: seen from above, the planned footprints (sole rectangles), the
//!   planned CoM on the floor, the measured centre of pressure (dots, one per tick) and the
//!   measured path of the base;
//! - `walk_joints.svg`: every leg joint, commanded (ik_solver's `joint_commands`) against
//!   measured (the simulator's `joint_states`), over simulated time;
//! - `walk_frames.svg`: a contact sheet of the measured robot, side view, at evenly spaced
//!   instants: every link drawn from the recorded base pose and joint angles through the
//!   URDF's forward kinematics, over the floor.

use std::path::{Path, PathBuf};

use anyhow::Context;
use gait_planner::{GaitPlanner, GaitSample};
use ik_solver::{BipedModel, Side};
use plotters::prelude::*;

use super::record::Recording;
use super::report::{WalkSummary, joints_in_model_order};
use crate::plots::{
    BASE_COLOUR, COM_COLOUR, LEGEND_FONT, LEGEND_W_PX, LegendEntry, MARGIN_PX, Swatch, TICK_FONT,
    TITLE_H_PX, Window, X_LABELS_PX, Y_LABELS_PX, draw_footprint, draw_legend, draw_title,
    floor_chart, planted_footprints, render, side_colour,
};

const COP_COLOUR: RGBColor = RGBColor(255, 127, 14);
const MEASURED_COLOUR: RGBColor = RGBColor(20, 20, 20);

/// Writes the pictures into `dir`; returns their paths.
pub fn write_pictures(
    dir: &Path,
    model: &BipedModel,
    planner: &GaitPlanner,
    plan: &[GaitSample],
    rec: &Recording,
    summary: &WalkSummary,
) -> anyhow::Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for (name, svg) in [
        ("walk_top_view.svg", top_view(planner, plan, rec, summary)?),
        ("walk_joints.svg", joints(model, rec, summary)?),
        ("walk_frames.svg", frames(model, rec, summary)?),
    ] {
        let p = dir.join(name);
        std::fs::write(&p, svg).with_context(|| format!("cannot write {}", p.display()))?;
        out.push(p);
    }
    Ok(out)
}

fn fell_text(summary: &WalkSummary) -> String {
    match &summary.measured.fell {
        Some(f) => format!("FELL at {:.2} s ({})", f.t_s, f.reason),
        None => "no fall".into(),
    }
}

fn top_view(
    planner: &GaitPlanner,
    plan: &[GaitSample],
    rec: &Recording,
    summary: &WalkSummary,
) -> anyhow::Result<String> {
    const WIDTH_PX: u32 = 1400;
    let start_s = summary.walk_started_s;
    // The plan starts at t = 0 at the world origin; the walk at `start_s`, from where the
    // robot settled: shift the plan onto the measured start.
    let (dx, dy) = rec
        .base
        .range((start_s * 1e9).round() as i64..)
        .next()
        .map_or((0.0, 0.0), |(_, b)| {
            let p0 = plan.first().map_or(nalgebra::Vector3::zeros(), |s| {
                s.base_world.translation.vector
            });
            (b.translation.x - p0.x, b.translation.y - p0.y)
        });
    let feet = planted_footprints(planner, plan);
    let com: Vec<(f64, f64)> = plan
        .iter()
        .map(|s| (s.com_world_m.x + dx, s.com_world_m.y + dy))
        .collect();
    let walk_ns = (start_s * 1e9).round() as i64;
    let base: Vec<(f64, f64)> = rec
        .base
        .range(walk_ns..)
        .map(|(_, b)| (b.translation.x, b.translation.y))
        .collect();
    let cop: Vec<(f64, f64)> = rec
        .cop
        .range(walk_ns..)
        .map(|(_, c)| (c[0], c[1]))
        .collect();
    let window = Window::around(
        feet.iter()
            .flat_map(|f| f.corners_m.iter().map(|c| (c[0] + dx, c[1] + dy)))
            .chain(com.iter().copied())
            .chain(base.iter().copied()),
    )
    .context("nothing to plot")?
    .padded(0.015);
    let plot_w_px = WIDTH_PX - LEGEND_W_PX - 2 * MARGIN_PX - Y_LABELS_PX;
    let (window, plot_h_px) = window.with_equal_scale(plot_w_px, 240..700);
    let height_px = TITLE_H_PX + 2 * MARGIN_PX + X_LABELS_PX + plot_h_px;
    let m = &summary.measured;
    let title = format!(
        "Simulated walk from above: {:.3} m of {:.3} m planned, {}",
        m.distance_m,
        m.planned_distance_m,
        fell_text(summary)
    );
    let subtitle = format!(
        "{}: CoP inside the support polygon {:.1}% of {} ticks; heading drift {:.2}°, max tilt {:.2}°",
        summary.robot,
        m.cop_inside_fraction * 100.0,
        m.cop_samples,
        m.heading_drift_deg,
        m.max_tilt_deg
    );
    render((WIDTH_PX, height_px), |root| {
        let (head, body) = root.split_vertically(TITLE_H_PX);
        draw_title(&head, &title, &subtitle)?;
        let (plot_area, legend_area) = body.split_horizontally(WIDTH_PX - LEGEND_W_PX);
        let mut chart = floor_chart(&plot_area, &window)?;
        for f in &feet {
            draw_footprint(&mut chart, f, (dx, dy), 0.15)?;
        }
        chart.draw_series(
            cop.iter()
                .map(|&p| Circle::new(p, 2, COP_COLOUR.mix(0.6).filled())),
        )?;
        chart.draw_series(LineSeries::new(
            com.iter().copied(),
            COM_COLOUR.stroke_width(2),
        ))?;
        chart.draw_series(LineSeries::new(
            base.iter().copied(),
            BASE_COLOUR.stroke_width(3),
        ))?;
        draw_legend(
            &legend_area,
            &[
                LegendEntry::new(Swatch::Fill(side_colour(Side::Left)), "left sole (plan)"),
                LegendEntry::new(Swatch::Fill(side_colour(Side::Right)), "right sole (plan)"),
                LegendEntry::new(Swatch::Line(COM_COLOUR), "CoM (plan)"),
                LegendEntry::new(Swatch::Dot(COP_COLOUR, true), "CoP (measured)"),
                LegendEntry::new(Swatch::Line(BASE_COLOUR), "base (measured)"),
            ],
        )
    })
}

fn joints(model: &BipedModel, rec: &Recording, summary: &WalkSummary) -> anyhow::Result<String> {
    const WIDTH_PX: u32 = 1400;
    const PANEL_H_PX: u32 = 150;
    let leg_joints: Vec<(Side, String)> = model
        .leg_joints()
        .map(|(s, j)| (s, j.name.clone()))
        .collect();
    let n = leg_joints.len().div_ceil(2) as u32;
    let height_px = TITLE_H_PX + n * PANEL_H_PX + X_LABELS_PX + MARGIN_PX;
    let t0 = summary.walk_started_s - 0.5;
    let t1 = summary.walk_started_s + summary.walk_duration_s + 0.5;
    let range_ns = (t0 * 1e9) as i64..(t1 * 1e9) as i64;
    let title = format!(
        "Leg joints, commanded and measured: largest difference {:.1}° ({})",
        summary.max_joint_tracking_error_rad.to_degrees(),
        summary.max_joint_tracking_error_joint
    );
    let subtitle = "thin coloured: the command (ik_solver's joint_commands); black: measured (the simulator's joint_states); degrees against simulated seconds";
    render((WIDTH_PX, height_px), |root| {
        let (head, body) = root.split_vertically(TITLE_H_PX);
        draw_title(&head, &title, subtitle)?;
        let (left, right) = body.split_horizontally(WIDTH_PX / 2);
        for (col, area) in [left, right].into_iter().enumerate() {
            let mut rest = area;
            let side = Side::BOTH[col];
            let names: Vec<&String> = leg_joints
                .iter()
                .filter(|(s, _)| *s == side)
                .map(|(_, n)| n)
                .collect();
            for (k, name) in names.iter().enumerate() {
                let is_last = k + 1 == names.len();
                let h = PANEL_H_PX + if is_last { X_LABELS_PX } else { 0 };
                let (panel, below) = rest.split_vertically(h);
                rest = below;
                let commanded: Vec<(f64, f64)> = rec
                    .commands
                    .range(range_ns.clone())
                    .filter_map(|(&t, c)| {
                        c.iter()
                            .find(|(n, _)| n == *name)
                            .map(|(_, v)| (t as f64 * 1e-9, v.to_degrees()))
                    })
                    .collect();
                let measured: Vec<(f64, f64)> = rec
                    .states
                    .range(range_ns.clone())
                    .filter_map(|(&t, js)| {
                        js.name
                            .iter()
                            .position(|n| n == *name)
                            .and_then(|i| js.position.get(i))
                            .map(|v| (t as f64 * 1e-9, v.to_degrees()))
                    })
                    .collect();
                let (lo, hi) = commanded
                    .iter()
                    .chain(&measured)
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                        (lo.min(p.1), hi.max(p.1))
                    });
                let (lo, hi) = if lo <= hi { (lo, hi) } else { (-1.0, 1.0) };
                let pad = ((hi - lo) * 0.1).max(1.0);
                let mut chart = ChartBuilder::on(&panel)
                    .margin(MARGIN_PX / 2)
                    .x_label_area_size(if is_last { X_LABELS_PX } else { 0 })
                    .y_label_area_size(Y_LABELS_PX)
                    .caption(name.as_str(), ("sans-serif", LEGEND_FONT))
                    .build_cartesian_2d(t0..t1, (lo - pad)..(hi + pad))?;
                let mut mesh = chart.configure_mesh();
                mesh.y_labels(4)
                    .label_style(("sans-serif", TICK_FONT))
                    .y_label_formatter(&|v| format!("{v:.0}"))
                    .light_line_style(WHITE.mix(0.0));
                if is_last {
                    mesh.x_desc("simulated time (s)");
                }
                mesh.draw()?;
                chart.draw_series(LineSeries::new(
                    commanded,
                    side_colour(side).stroke_width(3),
                ))?;
                chart.draw_series(LineSeries::new(measured, MEASURED_COLOUR.stroke_width(1)))?;
            }
        }
        Ok(())
    })
}

fn frames(model: &BipedModel, rec: &Recording, summary: &WalkSummary) -> anyhow::Result<String> {
    const COLS: u32 = 6;
    const ROWS: u32 = 2;
    const CELL_W_PX: u32 = 230;
    const CELL_H_PX: u32 = 300;
    let width_px = COLS * CELL_W_PX;
    let height_px = TITLE_H_PX + ROWS * CELL_H_PX;
    let start = summary.walk_started_s;
    let end = start + summary.walk_duration_s;
    let n = (COLS * ROWS) as usize;
    let instants: Vec<f64> = (0..n)
        .map(|k| start + (end - start) * k as f64 / (n - 1) as f64)
        .collect();
    let robot = model.robot();
    // Each link as a segment from its parent joint to itself, in the x–z plane.
    let mut sketches = Vec::new();
    for &t in &instants {
        let t_ns = (t * 1e9).round() as i64;
        let Some((&ts, js)) = rec.states.range(..=t_ns).next_back() else {
            continue;
        };
        let Some(base) = rec.base.get(&ts) else {
            continue;
        };
        let q = joints_in_model_order(model, &js.name, &js.position)?;
        let poses = robot.link_poses(base, &q)?;
        let mut segments = Vec::new();
        for j in robot.joints() {
            let a = poses[j.parent].translation.vector;
            let b = poses[j.child].translation.vector;
            let side = Side::BOTH.into_iter().find(|&s| {
                let Some(hip) = model.leg(s).present().next().map(|(_, lj)| lj.joint) else {
                    return false;
                };
                let mut link = j.child;
                while let Some(pj) = robot.links()[link].parent_joint {
                    if pj == hip {
                        return true;
                    }
                    link = robot.joints()[pj].parent;
                }
                false
            });
            segments.push(((a.x, a.z), (b.x, b.z), side));
        }
        // The soles, heel to toe.
        for side in Side::BOTH {
            let leg = model.leg(side);
            let c = model.sole_centre_world(&poses, side);
            let turn = poses[leg.foot_link].rotation * leg.foot_rotation0.inverse();
            let half = turn * nalgebra::Vector3::new(leg.sole.length_m() / 2.0, 0.0, 0.0);
            let (heel, toe) = (c - half, c + half);
            segments.push(((heel.x, heel.z), (toe.x, toe.z), Some(side)));
        }
        sketches.push((ts as f64 * 1e-9, segments));
    }
    let z_top = sketches
        .iter()
        .flat_map(|(_, s)| s.iter().flat_map(|(a, b, _)| [a.1, b.1]))
        .fold(0.0f64, f64::max);
    let span = (z_top + 0.05).max(0.1);
    let title = format!(
        "The walk in {} frames, side view (measured): {}",
        sketches.len(),
        fell_text(summary)
    );
    let subtitle = format!(
        "{}: links from the recorded base pose and joint angles; x forward (m) across, height up; same scale in every frame",
        summary.robot
    );
    render((width_px, height_px), |root| {
        let (head, body) = root.split_vertically(TITLE_H_PX);
        draw_title(&head, &title, &subtitle)?;
        let cells = body.split_evenly((ROWS as usize, COLS as usize));
        for (cell, (t, segments)) in cells.iter().zip(&sketches) {
            let cx =
                segments.iter().map(|(a, _, _)| a.0).sum::<f64>() / segments.len().max(1) as f64;
            let half = span * f64::from(CELL_W_PX) / f64::from(CELL_H_PX) / 2.0;
            let mut chart = ChartBuilder::on(cell)
                .margin(6)
                .caption(format!("t = {t:.2} s"), ("sans-serif", LEGEND_FONT))
                .build_cartesian_2d((cx - half)..(cx + half), -0.02..span)?;
            chart.draw_series(std::iter::once(PathElement::new(
                vec![(cx - half, 0.0), (cx + half, 0.0)],
                BLACK.mix(0.5).stroke_width(2),
            )))?;
            for (a, b, side) in segments {
                let colour = side.map_or(MEASURED_COLOUR, side_colour);
                chart.draw_series(std::iter::once(PathElement::new(
                    vec![*a, *b],
                    colour.stroke_width(3),
                )))?;
            }
        }
        Ok(())
    })
}
