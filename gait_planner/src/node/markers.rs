//! `gait/markers`: a tick's balance ([`gait_planner::BalanceView`]) as RViz / Foxglove
//! markers, in the walk's frame (`odom`), on the floor.

use crate::BalanceView;
use biped_msgs::msg::{ColorRGBA, Header, Marker, MarkerArray, Point};
use ik_solver::Side;

/// Slightly above the floor, so the floor's grid does not hide the lines.
const FLOOR_Z_M: f64 = 0.002;
const GREEN: ColorRGBA = ColorRGBA::rgba(0.1, 0.8, 0.2, 1.0);
const ORANGE: ColorRGBA = ColorRGBA::rgba(1.0, 0.55, 0.0, 1.0);
const RED: ColorRGBA = ColorRGBA::rgba(0.9, 0.1, 0.1, 1.0);
const BLUE: ColorRGBA = ColorRGBA::rgba(0.2, 0.4, 1.0, 1.0);

/// The namespaces, for the README: `support_polygon` (line), `com` (sphere: green with the
/// margin kept, red below it), `com_margin` (translucent disc of radius `min_com_margin_m`
/// around the CoM: it stays inside the polygon), `margin` (the margin in mm, as text),
/// `footsteps` (the swinging foot's landing; id 0 left, 1 right, deleted when not swinging).
pub fn balance_markers(view: &BalanceView, header: &Header) -> MarkerArray {
    let com = Point {
        x: view.com_xy[0],
        y: view.com_xy[1],
        z: FLOOR_Z_M,
    };
    let kept = view.margin_m >= view.min_margin_m;
    let mut markers = vec![
        Marker::closed_line(
            header,
            "support_polygon",
            0,
            &view.support_polygon,
            FLOOR_Z_M,
            0.003,
            GREEN,
        ),
        Marker::sphere(header, "com", 0, com, 0.012, if kept { GREEN } else { RED }),
        Marker::disc(
            header,
            "com_margin",
            0,
            com,
            2.0 * view.min_margin_m,
            ColorRGBA::rgba(1.0, 0.55, 0.0, 0.35),
        ),
        Marker::text(
            header,
            "margin",
            0,
            Point { z: 0.03, ..com },
            format!("margin {:.1} mm", view.margin_m * 1e3),
            0.012,
            if kept { ORANGE } else { RED },
        ),
    ];
    for side in Side::BOTH {
        let id = side.index() as i32;
        markers.push(match view.footsteps.iter().find(|(s, _)| *s == side) {
            Some((_, corners)) => {
                Marker::closed_line(header, "footsteps", id, corners, FLOOR_Z_M, 0.003, BLUE)
            }
            None => Marker::delete(header, "footsteps", id),
        });
    }
    MarkerArray { markers }
}
