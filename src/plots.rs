//! Pictures of a planned walk, written as SVG next to the plan CSV by `biped plan`.
//!
//! - `top_view.svg`: the walk seen from above, like the paper's Fig. 7.1–14. x (forward) to
//!   the right, y (left) upwards, the same number of pixels per metre on both axes. Every
//!   footprint where a foot stood on the floor is drawn as its sole rectangle (left and right
//!   feet in two colours, labelled with the swing that put them there, 0 for the initial
//!   stance), with the floor path of the whole-body CoM (the zig-zag from foot to foot) and
//!   the path of the pelvis over them, start and end marked.
//! - `swing_curve.svg`: the swing-ankle curve of the paper's Fig. 17 for the first full step
//!   of the plan: the swing ankle's height above the floor against its travel (along the step) since
//!   lift-off (mm, equal scales), as planned tick by tick, with the closed form of
//!   [`gait_planner::trajectory`] drawn over it so the two can be seen to coincide.
//! - `joint_angles.svg`: the leg joint angles (degrees) over time, one panel per joint role
//!   (hip yaw if the legs have one, hip roll, hip pitch, knee, ankle pitch, ankle roll), left
//!   and right legs in the colours of the top view, under a strip naming the phases, whose
//!   boundaries are drawn faintly across every panel.
//!
//! The SVG text is laid out with plotters' built-in size estimate, so no font is needed to
//! write the files; the viewer renders the `sans-serif` text with its own fonts.

use std::collections::HashSet;
use std::ops::Range;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use gait_planner::trajectory::{SWING_LIFT_FRACTION, swing_advance, swing_height};
use gait_planner::{GaitPlanner, GaitSample, PhaseKind};
use ik_solver::{JointRole, Side};
use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

pub(crate) type Area<'a> = DrawingArea<SVGBackend<'a>, Shift>;

/// Colour of everything about the left leg.
pub(crate) const LEFT_COLOUR: RGBColor = RGBColor(31, 119, 180);
/// Colour of everything about the right leg.
pub(crate) const RIGHT_COLOUR: RGBColor = RGBColor(214, 39, 40);
/// The CoM floor path.
pub(crate) const COM_COLOUR: RGBColor = RGBColor(20, 20, 20);
/// The pelvis path.
/// The planned ZMP's trace.
pub(crate) const ZMP_COLOUR: RGBColor = RGBColor(255, 127, 14);
pub(crate) const BASE_COLOUR: RGBColor = RGBColor(148, 103, 189);
/// Start marker.
pub(crate) const START_COLOUR: RGBColor = RGBColor(44, 160, 44);
/// The closed-form swing curve.
const FORMULA_COLOUR: RGBColor = RGBColor(20, 20, 20);

/// Height of the title block of every picture (px).
pub(crate) const TITLE_H_PX: u32 = 64;
/// Width of the legend column on the right of every picture (px).
pub(crate) const LEGEND_W_PX: u32 = 260;
/// Space around a chart (px).
pub(crate) const MARGIN_PX: u32 = 16;
/// Space for the y tick labels and axis name (px).
pub(crate) const Y_LABELS_PX: u32 = 90;
/// Space for the x tick labels and axis name (px).
pub(crate) const X_LABELS_PX: u32 = 60;
/// Tick label font size (plotters size; the SVG font size is this / 1.24).
pub(crate) const TICK_FONT: f64 = 17.0;
/// Axis name font size.
pub(crate) const AXIS_FONT: f64 = 19.0;
/// Legend and caption font size.
pub(crate) const LEGEND_FONT: f64 = 18.0;
/// Floating-point slack for "the foot is on the floor" (m).
const ON_FLOOR_TOL_M: f64 = 1e-9;

/// Writes `top_view.svg`, `swing_curve.svg` and `joint_angles.svg` into `dir` (created if
/// needed) and returns their paths.
pub fn write_plots(
    dir: &Path,
    planner: &GaitPlanner,
    samples: &[GaitSample],
) -> anyhow::Result<Vec<PathBuf>> {
    if samples.is_empty() {
        bail!("nothing to plot: the plan has no samples");
    }
    if !dir.as_os_str().is_empty() {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create folder {}", dir.display()))?;
    }
    type Draw = fn(&GaitPlanner, &[GaitSample]) -> anyhow::Result<String>;
    let pictures: [(&str, Draw); 3] = [
        ("top_view.svg", top_view),
        ("swing_curve.svg", swing_curve),
        ("joint_angles.svg", joint_angles),
    ];
    let mut written = Vec::new();
    for (name, draw) in pictures {
        let path = dir.join(name);
        let svg =
            draw(planner, samples).with_context(|| format!("cannot draw {}", path.display()))?;
        std::fs::write(&path, svg).with_context(|| format!("cannot write {}", path.display()))?;
        written.push(path);
    }
    Ok(written)
}

// ---------------------------------------------------------------------------------------
// Picture 1: top view.

/// A footprint: where a foot stood on the floor.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Footprint {
    pub(crate) side: Side,
    /// Sole corners on the floor (m).
    pub(crate) corners_m: [[f64; 2]; 4],
    /// The swing that put the foot there (0: the initial stance).
    pub(crate) step_index: u32,
}

/// Every distinct place where a foot stood on the floor (ankle at its initial height), in
/// the order the feet got there.
pub(crate) fn planted_footprints(planner: &GaitPlanner, samples: &[GaitSample]) -> Vec<Footprint> {
    let Some(first) = samples.first() else {
        return Vec::new();
    };
    let floor_z_m = first.ankles_world_m.map(|a| a.z);
    let mut seen = HashSet::new();
    let mut out = Vec::new();
    for s in samples {
        for side in Side::BOTH {
            let a = s.ankles_world_m[side.index()];
            if (a.z - floor_z_m[side.index()]).abs() > ON_FLOOR_TOL_M {
                continue;
            }
            // Footprints closer than a micrometre (and a microradian) are the same footprint.
            let yaw = s.feet_yaw_rad[side.index()];
            let key = (
                side.index(),
                (a.x * 1e6).round() as i64,
                (a.y * 1e6).round() as i64,
                (yaw * 1e6).round() as i64,
            );
            if seen.insert(key) {
                let corners_m = planner.model().leg(side).sole.corners([a.x, a.y], yaw);
                out.push(Footprint {
                    side,
                    corners_m,
                    step_index: s.step_index,
                });
            }
        }
    }
    out
}

/// The footprint's name, "L3" for the left foot put down by swing 3, and where it goes:
/// centred on the sole's outer edge (m), then `dy_px` inwards, where the CoM path (which
/// runs to the sole centres) does not cross it.
fn footprint_label(f: &Footprint) -> (String, (f64, f64), VPos, i32) {
    let x_m = f.corners_m.iter().map(|c| c[0]).sum::<f64>() / 4.0;
    let ys = f.corners_m.iter().map(|c| c[1]);
    let (outer_y_m, v_pos, dy_px) = match f.side {
        Side::Left => (ys.fold(f64::NEG_INFINITY, f64::max), VPos::Top, 6),
        Side::Right => (ys.fold(f64::INFINITY, f64::min), VPos::Bottom, -6),
    };
    let name = format!(
        "{}{}",
        if f.side == Side::Left { "L" } else { "R" },
        f.step_index
    );
    (name, (x_m, outer_y_m), v_pos, dy_px)
}

pub(crate) fn side_colour(side: Side) -> RGBColor {
    match side {
        Side::Left => LEFT_COLOUR,
        Side::Right => RIGHT_COLOUR,
    }
}

/// Number of steps of the walk: the swings before the closing half step.
fn step_count(samples: &[GaitSample]) -> usize {
    let steps: HashSet<u32> = samples
        .iter()
        .filter(|s| matches!(s.phase, PhaseKind::HalfStep | PhaseKind::Step))
        .map(|s| s.step_index)
        .collect();
    steps.len()
}

/// "1 step", "4 steps".
fn steps_text(n: usize) -> String {
    if n == 1 {
        "1 step".to_string()
    } else {
        format!("{n} steps")
    }
}

fn min_margin_m(samples: &[GaitSample]) -> f64 {
    samples
        .iter()
        .map(|s| s.margin_m)
        .fold(f64::INFINITY, f64::min)
}

fn min_zmp_margin_m(samples: &[GaitSample]) -> f64 {
    samples
        .iter()
        .map(|s| s.zmp_margin_m)
        .fold(f64::INFINITY, f64::min)
}

fn top_view(planner: &GaitPlanner, samples: &[GaitSample]) -> anyhow::Result<String> {
    const WIDTH_PX: u32 = 1400;
    let feet = planted_footprints(planner, samples);
    let com_m: Vec<(f64, f64)> = samples
        .iter()
        .map(|s| (s.com_world_m.x, s.com_world_m.y))
        .collect();
    let base_m: Vec<(f64, f64)> = samples
        .iter()
        .map(|s| (s.base_world.translation.x, s.base_world.translation.y))
        .collect();
    let zmp_m: Vec<(f64, f64)> = samples
        .iter()
        .map(|s| (s.zmp_xy_m[0], s.zmp_xy_m[1]))
        .collect();
    let corners = feet
        .iter()
        .flat_map(|f| f.corners_m.iter().map(|c| (c[0], c[1])));
    let window = Window::around(
        corners
            .chain(com_m.iter().copied())
            .chain(zmp_m.iter().copied())
            .chain(base_m.iter().copied()),
    )
    .context("no finite positions to plot")?
    .padded(0.015);
    let plot_w_px = WIDTH_PX - LEGEND_W_PX - 2 * MARGIN_PX - Y_LABELS_PX;
    let (window, plot_h_px) = window.with_equal_scale(plot_w_px, 240..700);
    let height_px = TITLE_H_PX + 2 * MARGIN_PX + X_LABELS_PX + plot_h_px;

    let cfg = planner.config();
    let stride = planner.stride();
    let title = format!(
        "Top view: {} of {:.0} mm forward, {:.0} mm left, {:.1}° turn; least margins CoM {:.1} mm, ZMP {:.1} mm",
        steps_text(step_count(samples)),
        stride.forward_m * 1e3,
        stride.left_m * 1e3,
        stride.turn_rad.to_degrees(),
        min_margin_m(samples) * 1e3,
        min_zmp_margin_m(samples) * 1e3,
    );
    let subtitle = format!(
        "{}: footprints where a foot stood (numbered by the swing that put it there), CoM, ZMP (cart-table model) and pelvis paths; margins required {:.1} mm, {:.1} mm; equal scales",
        planner.model().robot().name(),
        cfg.min_com_margin_m * 1e3,
        cfg.min_zmp_margin_m * 1e3
    );
    render((WIDTH_PX, height_px), |root| {
        let (head, body) = root.split_vertically(TITLE_H_PX);
        draw_title(&head, &title, &subtitle)?;
        let (plot_area, legend_area) = body.split_horizontally(WIDTH_PX - LEGEND_W_PX);
        let mut chart = floor_chart(&plot_area, &window)?;
        for f in &feet {
            let colour = side_colour(f.side);
            draw_footprint(&mut chart, f, (0.0, 0.0), 0.18)?;
            let (name, at, v_pos, dy_px) = footprint_label(f);
            let style = text_style(LEGEND_FONT)
                .color(&colour)
                .pos(Pos::new(HPos::Center, v_pos));
            chart.draw_series(std::iter::once(
                EmptyElement::at(at) + Text::new(name, (0, dy_px), style),
            ))?;
        }
        chart.draw_series(DashedLineSeries::new(
            base_m.iter().copied(),
            8,
            5,
            BASE_COLOUR.stroke_width(2),
        ))?;
        chart.draw_series(LineSeries::new(
            zmp_m.iter().copied(),
            ZMP_COLOUR.stroke_width(1),
        ))?;
        chart.draw_series(LineSeries::new(
            com_m.iter().copied(),
            COM_COLOUR.stroke_width(2),
        ))?;
        if let (Some(&start), Some(&end)) = (com_m.first(), com_m.last()) {
            chart.draw_series(std::iter::once(Circle::new(
                start,
                7,
                START_COLOUR.filled(),
            )))?;
            chart.draw_series(std::iter::once(Circle::new(
                end,
                7,
                COM_COLOUR.stroke_width(2),
            )))?;
        }
        draw_legend(
            &legend_area,
            &[
                LegendEntry::new(Swatch::Fill(LEFT_COLOUR), "left footprint"),
                LegendEntry::new(Swatch::Fill(RIGHT_COLOUR), "right footprint"),
                LegendEntry::new(Swatch::Line(COM_COLOUR), "CoM on the floor"),
                LegendEntry::new(Swatch::Line(ZMP_COLOUR), "ZMP (planned)"),
                LegendEntry::new(Swatch::Dashed(BASE_COLOUR), "pelvis (base link)"),
                LegendEntry::new(Swatch::Dot(START_COLOUR, true), "start"),
                LegendEntry::new(Swatch::Dot(COM_COLOUR, false), "end"),
            ],
        )
    })
}

/// The chart type of [`floor_chart`].
pub(crate) type FloorChart<'a, 'b> = ChartContext<
    'a,
    SVGBackend<'b>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// A footprint's sole rectangle moved by `shift_m`, filled with its side's colour at
/// `fill_alpha` and outlined.
pub(crate) fn draw_footprint(
    chart: &mut FloorChart<'_, '_>,
    f: &Footprint,
    shift_m: (f64, f64),
    fill_alpha: f64,
) -> anyhow::Result<()> {
    let colour = side_colour(f.side);
    let pts: Vec<(f64, f64)> = f
        .corners_m
        .iter()
        .map(|c| (c[0] + shift_m.0, c[1] + shift_m.1))
        .collect();
    chart.draw_series(std::iter::once(Polygon::new(
        pts.clone(),
        colour.mix(fill_alpha).filled(),
    )))?;
    let mut outline = pts.clone();
    outline.extend(pts.first().copied());
    chart.draw_series(std::iter::once(PathElement::new(
        outline,
        colour.stroke_width(2),
    )))?;
    Ok(())
}

/// A chart of the floor seen from above over `window` (m): x forward to the right, y left
/// upwards, labelled axes and a faint grid.
pub(crate) fn floor_chart<'a, 'b>(
    area: &'a Area<'b>,
    window: &Window,
) -> anyhow::Result<FloorChart<'a, 'b>> {
    let mut chart = ChartBuilder::on(area)
        .margin(MARGIN_PX)
        .x_label_area_size(X_LABELS_PX)
        .y_label_area_size(Y_LABELS_PX)
        .build_cartesian_2d(window.x.clone(), window.y.clone())?;
    chart
        .configure_mesh()
        .x_desc("x forward (m)")
        .y_desc("y left (m)")
        .x_label_formatter(&|v| format!("{v:.2}"))
        .y_label_formatter(&|v| format!("{v:.2}"))
        .label_style(("sans-serif", TICK_FONT))
        .axis_desc_style(("sans-serif", AXIS_FONT))
        .light_line_style(BLACK.mix(0.04))
        .bold_line_style(BLACK.mix(0.12))
        .draw()?;
    Ok(chart)
}

// ---------------------------------------------------------------------------------------
// Picture 2: the swing-ankle curve.

/// The swing analysed by the swing-curve picture.
#[derive(Debug, Clone, PartialEq)]
struct Swing {
    kind: PhaseKind,
    side: Side,
    step_index: u32,
    /// (travel along the step since lift-off, height above the floor) of each tick, from the tick
    /// before lift-off to touch-down (mm).
    ticks_mm: Vec<(f64, f64)>,
    /// Forward travel from lift-off to touch-down (mm).
    travel_mm: f64,
    duration_s: f64,
}

/// The first full step of the plan (or, in a walk too short to have one, its first swing).
fn first_swing(samples: &[GaitSample]) -> Option<Swing> {
    let kinds = [
        PhaseKind::Step,
        PhaseKind::HalfStep,
        PhaseKind::FinalHalfStep,
    ];
    let floor_z_m = samples.first()?.ankles_world_m.map(|a| a.z);
    kinds.into_iter().find_map(|kind| {
        let start = samples.iter().position(|s| s.phase == kind)?;
        let len = samples[start..]
            .iter()
            .take_while(|s| s.phase == kind)
            .count();
        let phase = &samples[start..start + len];
        let side = match phase.first()?.support {
            gait_planner::Support::Left => Side::Right,
            gait_planner::Support::Right => Side::Left,
            gait_planner::Support::Double => return None,
        };
        // The tick before the phase ends the previous phase with the foot still down.
        let with_lift_off = &samples[start.saturating_sub(1)..start + len];
        let (first, last) = (with_lift_off.first()?, with_lift_off.last()?);
        let a0 = first.ankles_world_m[side.index()];
        let z0_m = floor_z_m[side.index()];
        // Horizontal travel along the step's direction (forward, back or sideways).
        let travel = (last.ankles_world_m[side.index()] - a0).xy();
        let along = if travel.norm() > 1e-9 {
            travel.normalize()
        } else {
            nalgebra::Vector2::x()
        };
        let ticks_mm = with_lift_off
            .iter()
            .map(|s| {
                let a = s.ankles_world_m[side.index()];
                ((a - a0).xy().dot(&along) * 1e3, (a.z - z0_m) * 1e3)
            })
            .collect();
        Some(Swing {
            kind,
            side,
            step_index: phase.first()?.step_index,
            ticks_mm,
            travel_mm: travel.norm() * 1e3,
            duration_s: last.t_s - first.t_s,
        })
    })
}

/// The closed-form swing curve at `n` + 1 evenly spaced progress values (mm).
fn swing_formula_mm(travel_mm: f64, lift_mm: f64, n: usize) -> Vec<(f64, f64)> {
    (0..=n)
        .map(|k| {
            let p = k as f64 / n as f64;
            (travel_mm * swing_advance(p), lift_mm * swing_height(p))
        })
        .collect()
}

fn swing_curve(planner: &GaitPlanner, samples: &[GaitSample]) -> anyhow::Result<String> {
    const WIDTH_PX: u32 = 1300;
    const CAPTION_H_PX: u32 = 76;
    let swing = first_swing(samples).context("the plan has no swing")?;
    let lift_mm = planner.config().foot_lift_m * 1e3;
    let formula = swing_formula_mm(swing.travel_mm, lift_mm, 400);
    let window = Window::around(swing.ticks_mm.iter().chain(&formula).copied())
        .context("no finite swing positions to plot")?
        .padded(4.0);
    let plot_w_px = WIDTH_PX - LEGEND_W_PX - 2 * MARGIN_PX - Y_LABELS_PX;
    let (window, plot_h_px) = window.with_equal_scale(plot_w_px, 260..560);
    let height_px = TITLE_H_PX + 2 * MARGIN_PX + X_LABELS_PX + plot_h_px + CAPTION_H_PX;

    let which = match swing.kind {
        PhaseKind::Step => "first full step",
        PhaseKind::HalfStep => "first half step (the plan has no full step)",
        _ => "final half step (the plan has no full step)",
    };
    let title = format!(
        "Swing-ankle curve (paper Fig. 17): {which}, {} foot",
        swing.side
    );
    let subtitle = format!(
        "swing {}: travel L = {:.1} mm, foot lift h = {:.1} mm, {:.2} s; height against travel, equal scales",
        swing.step_index, swing.travel_mm, lift_mm, swing.duration_s
    );
    let colour = side_colour(swing.side);
    let rate_hz = planner.config().control_rate_hz;
    let lift_fraction = SWING_LIFT_FRACTION;
    let marks = [lift_fraction, 0.5, 1.0 - lift_fraction].map(|p| {
        (
            p,
            (
                swing.travel_mm * swing_advance(p),
                lift_mm * swing_height(p),
            ),
        )
    });
    render((WIDTH_PX, height_px), |root| {
        let (head, body) = root.split_vertically(TITLE_H_PX);
        draw_title(&head, &title, &subtitle)?;
        let (body, caption) = body.split_vertically(2 * MARGIN_PX + X_LABELS_PX + plot_h_px);
        let (plot_area, legend_area) = body.split_horizontally(WIDTH_PX - LEGEND_W_PX);
        let mut chart = ChartBuilder::on(&plot_area)
            .margin(MARGIN_PX)
            .x_label_area_size(X_LABELS_PX)
            .y_label_area_size(Y_LABELS_PX)
            .build_cartesian_2d(window.x.clone(), window.y.clone())?;
        chart
            .configure_mesh()
            .x_desc("travel along the step since lift-off (mm)")
            .y_desc("height above the floor, z − z₀ (mm)")
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| format!("{v:.0}"))
            .label_style(("sans-serif", TICK_FONT))
            .axis_desc_style(("sans-serif", AXIS_FONT))
            .light_line_style(BLACK.mix(0.04))
            .bold_line_style(BLACK.mix(0.12))
            .draw()?;
        // The floor.
        chart.draw_series(LineSeries::new(
            [(window.x.start, 0.0), (window.x.end, 0.0)],
            BLACK.mix(0.5).stroke_width(1),
        ))?;
        chart.draw_series(LineSeries::new(
            swing.ticks_mm.iter().copied(),
            colour.mix(0.35).stroke_width(7),
        ))?;
        chart.draw_series(
            swing
                .ticks_mm
                .iter()
                .map(|&p| Circle::new(p, 3, colour.filled())),
        )?;
        chart.draw_series(DashedLineSeries::new(
            formula.iter().copied(),
            6,
            4,
            FORMULA_COLOUR.stroke_width(2),
        ))?;
        for (p, at) in marks {
            chart.draw_series(std::iter::once(Circle::new(
                at,
                6,
                FORMULA_COLOUR.stroke_width(2),
            )))?;
            // Beside the mark, on the side away from the curve.
            let (h_pos, offset_px) = match p {
                p if p < 0.4 => (HPos::Left, (12, 0)),
                p if p > 0.6 => (HPos::Right, (-12, 0)),
                _ => (HPos::Center, (0, 14)),
            };
            let v_pos = if offset_px.1 > 0 {
                VPos::Top
            } else {
                VPos::Center
            };
            let style = text_style(LEGEND_FONT).pos(Pos::new(h_pos, v_pos));
            let label = format!("p = {p:.1}");
            chart.draw_series(std::iter::once(
                EmptyElement::at(at) + Text::new(label, offset_px, style),
            ))?;
        }
        draw_legend(
            &legend_area,
            &[
                LegendEntry::new(Swatch::Thick(colour), "planned swing ankle"),
                LegendEntry::new(
                    Swatch::Dot(colour, true),
                    format!("control ticks ({rate_hz:.0} Hz)"),
                ),
                LegendEntry::new(Swatch::Dashed(FORMULA_COLOUR), "closed form"),
                LegendEntry::new(Swatch::Dot(FORMULA_COLOUR, false), "phase progress p"),
            ],
        )?;
        let lines = [
            "z = h·s(4p(1−p)), s(v)=v²(3−2v);  x = L·m((p−0.2)/0.6), m = minimum-jerk",
            "p: progress through the swing, 0 to 1. The foot rises straight up until p = 0.2, travels forward until p = 0.8, then comes straight down.",
        ];
        for (k, line) in lines.iter().enumerate() {
            let size = if k == 0 {
                AXIS_FONT + 3.0
            } else {
                LEGEND_FONT - 1.0
            };
            let style = text_style(size).pos(Pos::new(HPos::Left, VPos::Center));
            caption.draw_text(
                line,
                &style,
                ((MARGIN_PX + Y_LABELS_PX) as i32, 22 + 32 * k as i32),
            )?;
        }
        Ok(())
    })
}

// ---------------------------------------------------------------------------------------
// Picture 3: joint angles over time.

/// A run of ticks in one phase.
#[derive(Debug, Clone, Copy, PartialEq)]
struct PhaseSpan {
    kind: PhaseKind,
    /// Where the span starts: the end of the previous one, or the first tick (s).
    start_s: f64,
    /// Time of the span's last tick (s).
    end_s: f64,
}

/// The phases of the plan, in order, back to back.
fn phase_spans(samples: &[GaitSample]) -> Vec<PhaseSpan> {
    let mut spans: Vec<PhaseSpan> = Vec::new();
    for s in samples {
        match spans.last_mut() {
            Some(last) if last.kind == s.phase => last.end_s = s.t_s,
            Some(last) => {
                let start_s = last.end_s;
                spans.push(PhaseSpan {
                    kind: s.phase,
                    start_s,
                    end_s: s.t_s,
                });
            }
            None => spans.push(PhaseSpan {
                kind: s.phase,
                start_s: s.t_s,
                end_s: s.t_s,
            }),
        }
    }
    spans
}

/// Background of a phase in the phase strip.
pub(crate) fn phase_colour(kind: PhaseKind) -> RGBColor {
    match kind {
        PhaseKind::Idle => RGBColor(235, 235, 235),
        PhaseKind::Crouch | PhaseKind::Rise => RGBColor(220, 220, 220),
        PhaseKind::Shift => RGBColor(255, 236, 179),
        PhaseKind::HalfStep | PhaseKind::FinalHalfStep => RGBColor(200, 230, 201),
        PhaseKind::Step => RGBColor(165, 214, 167),
        PhaseKind::Center => RGBColor(187, 222, 251),
    }
}

/// A shorter name for a phase whose full name does not fit its span.
fn phase_short_name(kind: PhaseKind) -> &'static str {
    match kind {
        PhaseKind::HalfStep => "half",
        PhaseKind::FinalHalfStep => "final",
        PhaseKind::Center => "ctr",
        PhaseKind::Crouch => "crch",
        _ => "",
    }
}

/// The angle of one leg joint over time (deg).
#[derive(Debug, Clone, PartialEq)]
struct JointSeries {
    side: Side,
    name: String,
    points_deg: Vec<(f64, f64)>,
}

/// The leg joints of each role present in either leg, hip to foot.
fn leg_joint_series(
    planner: &GaitPlanner,
    samples: &[GaitSample],
) -> Vec<(JointRole, Vec<JointSeries>)> {
    JointRole::ALL
        .into_iter()
        .filter_map(|role| {
            let series: Vec<JointSeries> = Side::BOTH
                .into_iter()
                .filter_map(|side| {
                    let joint = planner
                        .model()
                        .leg(side)
                        .present()
                        .find(|(r, _)| *r == role)?
                        .1;
                    let points_deg = samples
                        .iter()
                        .filter_map(|s| {
                            s.joints_rad.get(joint.dof).map(|q| (s.t_s, q.to_degrees()))
                        })
                        .collect();
                    Some(JointSeries {
                        side,
                        name: joint.name.clone(),
                        points_deg,
                    })
                })
                .collect();
            (!series.is_empty()).then_some((role, series))
        })
        .collect()
}

fn joint_angles(planner: &GaitPlanner, samples: &[GaitSample]) -> anyhow::Result<String> {
    const WIDTH_PX: u32 = 1400;
    const STRIP_H_PX: u32 = 44;
    const PANEL_H_PX: u32 = 170;
    /// Vertical space between panels (px).
    const GAP_PX: u32 = 8;
    let spans = phase_spans(samples);
    let panels = leg_joint_series(planner, samples);
    if panels.is_empty() {
        bail!("the robot model has no leg joints");
    }
    let (Some(first), Some(last)) = (samples.first(), samples.last()) else {
        bail!("nothing to plot")
    };
    let t_range = if last.t_s > first.t_s {
        first.t_s..last.t_s
    } else {
        first.t_s..first.t_s + 1.0
    };
    let n = panels.len() as u32;
    let height_px = TITLE_H_PX + STRIP_H_PX + n * (PANEL_H_PX + GAP_PX) + X_LABELS_PX + MARGIN_PX;
    let title = format!(
        "Leg joint angles: {} of {:.0} mm, {:.2} s",
        steps_text(step_count(samples)),
        planner.config().step_length_m * 1e3,
        last.t_s - first.t_s
    );
    let subtitle = format!(
        "{}: one panel per joint role, both legs; phase boundaries as faint lines",
        planner.model().robot().name()
    );
    let left_px = MARGIN_PX + Y_LABELS_PX;
    let plot_w_px = WIDTH_PX - LEGEND_W_PX - left_px - MARGIN_PX;
    render((WIDTH_PX, height_px), |root| {
        let (head, body) = root.split_vertically(TITLE_H_PX);
        draw_title(&head, &title, &subtitle)?;
        let (plots, legend_area) = body.split_horizontally(WIDTH_PX - LEGEND_W_PX);
        let (strip, mut rest) = plots.split_vertically(STRIP_H_PX);
        draw_phase_strip(
            &strip.margin(4, 4, left_px, MARGIN_PX),
            &spans,
            &t_range,
            plot_w_px,
        )?;
        for (k, (role, series)) in panels.iter().enumerate() {
            let is_last = k + 1 == panels.len();
            let h = PANEL_H_PX + GAP_PX + if is_last { X_LABELS_PX } else { 0 };
            let (panel, below) = rest.split_vertically(h);
            draw_joint_panel(&panel, *role, series, &spans, &t_range, is_last)?;
            rest = below;
        }
        let mut entries = vec![
            LegendEntry::new(Swatch::Line(LEFT_COLOUR), "left leg"),
            LegendEntry::new(Swatch::Line(RIGHT_COLOUR), "right leg"),
            LegendEntry::new(Swatch::None, ""),
        ];
        let mut kinds: Vec<PhaseKind> = Vec::new();
        for s in &spans {
            if !kinds.contains(&s.kind) {
                kinds.push(s.kind);
            }
        }
        entries.extend(
            kinds
                .into_iter()
                .map(|k| LegendEntry::new(Swatch::Band(phase_colour(k)), format!("phase {k}"))),
        );
        let joints: Vec<String> = Side::BOTH
            .into_iter()
            .flat_map(|side| {
                panels.iter().flat_map(move |(_, s)| {
                    s.iter()
                        .filter(move |j| j.side == side)
                        .map(|j| j.name.clone())
                })
            })
            .collect();
        draw_legend(&legend_area.margin(STRIP_H_PX, 0, 0, 0), &entries)?;
        draw_joint_names(&legend_area, &joints, height_px - TITLE_H_PX)
    })
}

/// The list of plotted URDF joints, one a line, at the bottom of the legend column.
fn draw_joint_names(area: &Area<'_>, names: &[String], area_h_px: u32) -> anyhow::Result<()> {
    const ROW_PX: i32 = 21;
    let top =
        area_h_px as i32 - MARGIN_PX as i32 - X_LABELS_PX as i32 - ROW_PX * names.len() as i32;
    let style = text_style(LEGEND_FONT - 2.0).pos(Pos::new(HPos::Left, VPos::Center));
    area.draw_text("URDF joints plotted:", &style, (14, top - ROW_PX))?;
    for (k, name) in names.iter().enumerate() {
        area.draw_text(name, &style, (28, top + ROW_PX * k as i32))?;
    }
    Ok(())
}

/// The phases as coloured bands along the time axis, named where the name fits.
fn draw_phase_strip(
    area: &Area<'_>,
    spans: &[PhaseSpan],
    t_range: &Range<f64>,
    plot_w_px: u32,
) -> anyhow::Result<()> {
    let mut chart = ChartBuilder::on(area).build_cartesian_2d(t_range.clone(), 0.0..1.0)?;
    let px_per_s = plot_w_px as f64 / (t_range.end - t_range.start);
    let font = LEGEND_FONT - 2.0;
    // plotters writes font-size = size / 1.24; a sans-serif character is about 0.6 em wide.
    let text_w_px = |s: &str| s.chars().count() as f64 * 0.6 * font / 1.24;
    for s in spans {
        chart.draw_series(std::iter::once(Rectangle::new(
            [(s.start_s, 0.0), (s.end_s, 1.0)],
            phase_colour(s.kind).filled(),
        )))?;
        chart.draw_series(std::iter::once(Rectangle::new(
            [(s.start_s, 0.0), (s.end_s, 1.0)],
            WHITE.stroke_width(1),
        )))?;
        let span_px = (s.end_s - s.start_s) * px_per_s - 6.0;
        let name = [s.kind.as_str(), phase_short_name(s.kind)]
            .into_iter()
            .find(|n| !n.is_empty() && text_w_px(n) <= span_px);
        if let Some(name) = name {
            let style = text_style(font).pos(Pos::new(HPos::Center, VPos::Center));
            chart.draw_series(std::iter::once(Text::new(
                name.to_string(),
                ((s.start_s + s.end_s) / 2.0, 0.5),
                style,
            )))?;
        }
    }
    Ok(())
}

/// One panel of the joint-angle picture: both legs' joint of one role.
fn draw_joint_panel(
    area: &Area<'_>,
    role: JointRole,
    series: &[JointSeries],
    spans: &[PhaseSpan],
    t_range: &Range<f64>,
    with_time_axis: bool,
) -> anyhow::Result<()> {
    let values = series
        .iter()
        .flat_map(|s| s.points_deg.iter().map(|p| p.1))
        .filter(|v| v.is_finite());
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    let (lo, hi) = if lo <= hi { (lo, hi) } else { (0.0, 0.0) };
    let span = (hi - lo).max(2.0);
    let mid = (hi + lo) / 2.0;
    let y_range = (mid - 0.6 * span)..(mid + 0.6 * span);
    let mut chart = ChartBuilder::on(area)
        .margin_left(MARGIN_PX)
        .margin_right(MARGIN_PX)
        .margin_bottom(if with_time_axis { 0 } else { 8 })
        .x_label_area_size(if with_time_axis { X_LABELS_PX } else { 0 })
        .y_label_area_size(Y_LABELS_PX)
        .build_cartesian_2d(t_range.clone(), y_range.clone())?;
    let desc = format!("{} (°)", role.as_str().replace('_', " "));
    // Whole degrees, unless the joint hardly moves.
    let decimals = if span < 5.0 { 1 } else { 0 };
    let y_label = |v: &f64| format!("{:.*}", decimals, v + 0.0);
    let mut mesh = chart.configure_mesh();
    mesh.y_desc(desc)
        .y_labels(5)
        .x_labels(16)
        .y_label_formatter(&y_label)
        .x_label_formatter(&|v| format!("{v:.0}"))
        .label_style(("sans-serif", TICK_FONT))
        .axis_desc_style(("sans-serif", AXIS_FONT))
        .light_line_style(WHITE.mix(0.0))
        .bold_line_style(BLACK.mix(0.08));
    if with_time_axis {
        mesh.x_desc("time (s)");
    }
    mesh.draw()?;
    for s in spans.iter().skip(1) {
        chart.draw_series(LineSeries::new(
            [(s.start_s, y_range.start), (s.start_s, y_range.end)],
            BLACK.mix(0.25).stroke_width(1),
        ))?;
    }
    for s in series {
        chart.draw_series(LineSeries::new(
            s.points_deg.iter().copied(),
            side_colour(s.side).stroke_width(2),
        ))?;
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------
// Shared pieces.

/// Renders a picture to SVG text.
pub(crate) fn render(
    size_px: (u32, u32),
    draw: impl FnOnce(&Area<'_>) -> anyhow::Result<()>,
) -> anyhow::Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size_px).into_drawing_area();
        root.fill(&WHITE)?;
        draw(&root)?;
        root.present()?;
    }
    Ok(svg)
}

pub(crate) fn text_style(size: f64) -> TextStyle<'static> {
    TextStyle::from(("sans-serif", size).into_font()).color(&BLACK)
}

/// A bold title and a grey subtitle, centred.
pub(crate) fn draw_title(area: &Area<'_>, title: &str, subtitle: &str) -> anyhow::Result<()> {
    let (w, _) = area.dim_in_pixel();
    let centre = Pos::new(HPos::Center, VPos::Center);
    let bold = TextStyle::from(("sans-serif", 27.0).into_font().style(FontStyle::Bold))
        .color(&BLACK)
        .pos(centre);
    area.draw_text(title, &bold, (w as i32 / 2, 22))?;
    let grey = RGBColor(90, 90, 90);
    area.draw_text(
        subtitle,
        &text_style(LEGEND_FONT).color(&grey).pos(centre),
        (w as i32 / 2, 50),
    )?;
    Ok(())
}

/// What a legend entry shows next to its label.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Swatch {
    /// Nothing: an empty row.
    None,
    /// A lightly filled, outlined box.
    Fill(RGBColor),
    /// A box in the full colour, as the phase strip draws it.
    Band(RGBColor),
    /// A solid line.
    Line(RGBColor),
    /// A broad translucent line.
    Thick(RGBColor),
    /// A dashed line.
    Dashed(RGBColor),
    /// A dot, filled or hollow.
    Dot(RGBColor, bool),
}

#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LegendEntry {
    swatch: Swatch,
    label: String,
}

impl LegendEntry {
    pub(crate) fn new(swatch: Swatch, label: impl Into<String>) -> Self {
        Self {
            swatch,
            label: label.into(),
        }
    }
}

/// A boxed legend at the top of `area` (pixel coordinates).
pub(crate) fn draw_legend(area: &Area<'_>, entries: &[LegendEntry]) -> anyhow::Result<()> {
    const ROW_PX: i32 = 30;
    const X0_PX: i32 = 14;
    const SWATCH_W_PX: i32 = 36;
    let top = MARGIN_PX as i32 + 8;
    let (w, _) = area.dim_in_pixel();
    let bottom = top + ROW_PX * entries.len() as i32;
    area.draw(&Rectangle::new(
        [(2, top - 8), (w as i32 - MARGIN_PX as i32, bottom - 6)],
        BLACK.mix(0.3).stroke_width(1),
    ))?;
    let label_style = text_style(LEGEND_FONT).pos(Pos::new(HPos::Left, VPos::Center));
    for (k, e) in entries.iter().enumerate() {
        let y = top + 8 + ROW_PX * k as i32;
        let (x0, x1) = (X0_PX, X0_PX + SWATCH_W_PX);
        match e.swatch {
            Swatch::None => {}
            Swatch::Fill(c) => {
                area.draw(&Rectangle::new(
                    [(x0, y - 9), (x1, y + 9)],
                    c.mix(0.3).filled(),
                ))?;
                area.draw(&Rectangle::new(
                    [(x0, y - 9), (x1, y + 9)],
                    c.stroke_width(2),
                ))?;
            }
            Swatch::Band(c) => {
                area.draw(&Rectangle::new([(x0, y - 9), (x1, y + 9)], c.filled()))?;
                area.draw(&Rectangle::new(
                    [(x0, y - 9), (x1, y + 9)],
                    BLACK.mix(0.3).stroke_width(1),
                ))?;
            }
            Swatch::Line(c) => {
                area.draw(&PathElement::new(vec![(x0, y), (x1, y)], c.stroke_width(2)))?
            }
            Swatch::Thick(c) => area.draw(&PathElement::new(
                vec![(x0, y), (x1, y)],
                c.mix(0.35).stroke_width(7),
            ))?,
            Swatch::Dashed(c) => area.draw(&DashedPathElement::new(
                vec![(x0, y), (x1, y)],
                8,
                5,
                c.stroke_width(2),
            ))?,
            Swatch::Dot(c, filled) => {
                let style = if filled {
                    c.filled()
                } else {
                    c.stroke_width(2)
                };
                area.draw(&Circle::new(((x0 + x1) / 2, y), 6, style))?;
            }
        }
        area.draw_text(&e.label, &label_style, (x1 + 10, y))?;
    }
    Ok(())
}

/// A rectangle of the data plane shown by a chart.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Window {
    pub(crate) x: Range<f64>,
    pub(crate) y: Range<f64>,
}

impl Window {
    /// The smallest window holding all finite points; `None` if there are none.
    pub(crate) fn around(points: impl IntoIterator<Item = (f64, f64)>) -> Option<Self> {
        let mut w: Option<Self> = None;
        for (x, y) in points
            .into_iter()
            .filter(|(x, y)| x.is_finite() && y.is_finite())
        {
            w = Some(match w {
                None => Self { x: x..x, y: y..y },
                Some(w) => Self {
                    x: w.x.start.min(x)..w.x.end.max(x),
                    y: w.y.start.min(y)..w.y.end.max(y),
                },
            });
        }
        w
    }

    /// The window grown by `pad` on every side.
    pub(crate) fn padded(self, pad: f64) -> Self {
        Self {
            x: self.x.start - pad..self.x.end + pad,
            y: self.y.start - pad..self.y.end + pad,
        }
    }

    /// The window grown about its centre so that, drawn `plot_w_px` wide, a data unit is as
    /// long along y as along x; with the plot height (px) that needs, kept within
    /// `plot_h_px` by widening the x range when the data are too tall.
    pub(crate) fn with_equal_scale(self, plot_w_px: u32, plot_h_px: Range<u32>) -> (Self, u32) {
        let (xs, ys) = (self.x.end - self.x.start, self.y.end - self.y.start);
        let w = f64::from(plot_w_px.max(1));
        let h = (ys / xs * w)
            .clamp(f64::from(plot_h_px.start), f64::from(plot_h_px.end))
            .round()
            .max(1.0);
        let per_px = (xs / w).max(ys / h);
        let grow = |r: Range<f64>, span: f64| {
            let c = (r.start + r.end) / 2.0;
            c - span / 2.0..c + span / 2.0
        };
        (
            Self {
                x: grow(self.x, per_px * w),
                y: grow(self.y, per_px * h),
            },
            h as u32,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_scale_gives_the_same_units_per_pixel_on_both_axes() {
        let w = Window {
            x: 0.0..0.3,
            y: -0.05..0.05,
        };
        let (w2, h) = w.with_equal_scale(900, 100..700);
        let (sx, sy) = (
            (w2.x.end - w2.x.start) / 900.0,
            (w2.y.end - w2.y.start) / f64::from(h),
        );
        assert!((sx - sy).abs() < 1e-12);
        assert_eq!(h, 300);
        // Too flat: the y range grows.
        let (w3, h3) = Window {
            x: 0.0..1.0,
            y: 0.0..0.01,
        }
        .with_equal_scale(500, 200..400);
        assert_eq!(h3, 200);
        assert!((w3.y.end - w3.y.start - 0.4).abs() < 1e-12);
        // Too tall: the x range grows.
        let (w4, h4) = Window {
            x: 0.0..0.1,
            y: 0.0..1.0,
        }
        .with_equal_scale(500, 200..400);
        assert_eq!(h4, 400);
        assert!((w4.x.end - w4.x.start - 1.25).abs() < 1e-12);
    }

    fn planner() -> GaitPlanner {
        let model = ik_solver::BipedModel::from_urdf_str(ik_solver::DEFAULT_URDF, None).unwrap();
        GaitPlanner::new(model, gait_planner::GaitParams::default()).unwrap()
    }

    #[test]
    fn an_empty_plan_is_refused() {
        let dir = std::env::temp_dir().join(format!("biped_plots_empty_{}", std::process::id()));
        let err = write_plots(&dir, &planner(), &[]).unwrap_err();
        assert!(err.to_string().contains("nothing to plot"), "{err}");
    }

    #[test]
    fn the_three_pictures_are_written_with_their_labels() {
        let dir = std::env::temp_dir().join(format!("biped_plots_{}", std::process::id()));
        let mut p = planner();
        let samples = p.plan(gait_planner::WalkRequest::Steps(2)).unwrap();
        let files = write_plots(&dir, &p, &samples).unwrap();
        assert_eq!(files.len(), 3);
        let text = |name: &str| std::fs::read_to_string(dir.join(name)).unwrap();
        let top = text("top_view.svg");
        assert!(
            top.contains("x forward (m)")
                && top.contains("left footprint")
                && top.contains("L0")
                && top.contains("ZMP (planned)")
        );
        let swing = text("swing_curve.svg");
        assert!(swing.contains("first full step") && swing.contains("minimum-jerk"));
        let joints = text("joint_angles.svg");
        assert!(
            joints.contains("knee (°)")
                && joints.contains("time (s)")
                && joints.contains("half_step")
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn swing_formula_starts_and_ends_on_the_floor() {
        let f = swing_formula_mm(90.0, 20.0, 100);
        let (a, b) = (f[0], f[100]);
        assert!(a.0.abs() < 1e-12 && a.1.abs() < 1e-12);
        assert!((b.0 - 90.0).abs() < 1e-12 && b.1.abs() < 1e-12);
        assert!((f[50].1 - 20.0).abs() < 1e-12);
    }
}
