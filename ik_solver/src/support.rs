//! Support polygons and a point's signed margin to them, in the floor plane (x, y in m): the
//! planned CoM's (gait_planner) and the measured centre of pressure's (sim_bridge).

/// A point on the floor (x, y), m.
pub type Xy = [f64; 2];

fn cross(o: Xy, a: Xy, b: Xy) -> f64 {
    (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
}

/// Convex hull, counter-clockwise, without repeated or collinear points (Andrew's monotone
/// chain).
pub fn convex_hull(points: &[Xy]) -> Vec<Xy> {
    let mut pts = points.to_vec();
    pts.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let mut hull: Vec<Xy> = Vec::with_capacity(2 * pts.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &Xy>> = if pass == 0 {
            Box::new(pts.iter())
        } else {
            Box::new(pts.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

fn segment_distance(p: Xy, a: Xy, b: Xy) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
}

/// Signed distance (m) from `p` to the boundary of the convex polygon `poly` (counter-
/// clockwise): positive inside, negative outside, zero on the edge.
///
/// ```
/// use ik_solver::support::signed_margin;
/// let square = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
/// assert_eq!(signed_margin(&square, [0.5, 0.25]), 0.25);
/// assert_eq!(signed_margin(&square, [2.0, 0.5]), -1.0);
/// ```
pub fn signed_margin(poly: &[Xy], p: Xy) -> f64 {
    let n = poly.len();
    if n < 3 {
        return f64::NEG_INFINITY;
    }
    let mut inside = f64::INFINITY;
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        let len = (b[0] - a[0]).hypot(b[1] - a[1]);
        if len > 0.0 {
            inside = inside.min(cross(a, b, p) / len);
        }
    }
    if inside >= 0.0 {
        inside
    } else {
        -(0..n)
            .map(|i| segment_distance(p, poly[i], poly[(i + 1) % n]))
            .fold(f64::INFINITY, f64::min)
    }
}

/// True when two convex polygons (either winding) share interior area: no edge normal of
/// either separates their projections (the separating-axis theorem). Touching edges do not
/// count as overlap.
pub fn convex_overlap(a: &[Xy], b: &[Xy]) -> bool {
    let separated_by_edges_of = |p: &[Xy]| {
        (0..p.len()).any(|i| {
            let (u, v) = (p[i], p[(i + 1) % p.len()]);
            let n = [-(v[1] - u[1]), v[0] - u[0]];
            let span = |q: &[Xy]| {
                q.iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), c| {
                        let d = n[0] * c[0] + n[1] * c[1];
                        (lo.min(d), hi.max(d))
                    })
            };
            let ((a0, a1), (b0, b1)) = (span(a), span(b));
            a1 <= b0 || b1 <= a0
        })
    };
    !(separated_by_edges_of(a) || separated_by_edges_of(b))
}
