//! What every physics test of a whole walk asserts about its report.

use walk_eval::WalkReport;

/// No fall, tilt under 10°, heading drift under 5°, the centre of pressure inside the support
/// polygon at least 99 % of the time, and the distance within 10 % of `want_m`.
pub fn assert_walked_well(report: &WalkReport, want_m: f64) {
    assert!(report.fell.is_none(), "fell: {:?}", report.fell);
    assert!(
        report.max_tilt_deg < 10.0,
        "tilt {} deg",
        report.max_tilt_deg
    );
    assert!(
        report.heading_drift_deg < 5.0,
        "heading drift {} deg",
        report.heading_drift_deg
    );
    assert!(
        report.cop_inside_fraction >= 0.99,
        "CoP inside the support polygon {:.4} of the time",
        report.cop_inside_fraction
    );
    assert!(
        (report.distance_m - want_m).abs() <= 0.1 * want_m,
        "walked {} m, the plan {} m",
        report.distance_m,
        want_m
    );
}
