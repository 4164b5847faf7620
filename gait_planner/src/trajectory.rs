//! Time profiles of the walk: the smooth ramp every phase uses, and the swing-ankle curve of
//! the paper's Fig. 17, both as closed forms of the phase progress `p` in [0, 1].

/// Minimum-jerk ramp from 0 to 1: `10p³ - 15p⁴ + 6p⁵`. Zero velocity and acceleration at
/// both ends, so every phase starts and ends at rest (the paper's `ProgresoTemporal` is a
/// linear ramp, whose velocity jumps at the phase ends). `p` outside [0, 1] is clamped.
///
/// ```
/// use gait_planner::trajectory::min_jerk;
/// assert_eq!(min_jerk(0.0), 0.0);
/// assert_eq!(min_jerk(0.5), 0.5);
/// assert_eq!(min_jerk(1.0), 1.0);
/// ```
pub fn min_jerk(p: f64) -> f64 {
    let p = p.clamp(0.0, 1.0);
    p * p * p * (10.0 + p * (-15.0 + 6.0 * p))
}

/// Part of the swing spent lifting before the foot starts forward (and, mirrored, lowering
/// after it stops).
pub const SWING_LIFT_FRACTION: f64 = 0.2;

/// Height of the swing ankle above its lift-off height, as a fraction of the foot lift:
/// `s(4p(1-p))` with the smoothstep `s(v) = v²(3 - 2v)`.
///
/// It has zero slope at lift-off and touch-down (no stamp), rises steeply through the first
/// fifth of the swing (70% of the lift is reached at p = 0.2), is nearly flat over the middle
/// while the foot travels forward, peaks at p = 0.5 and comes down as steeply as it rose:
/// the shape of the paper's Fig. 17, with the zero end velocities the paper lacks.
pub fn swing_height(p: f64) -> f64 {
    let p = p.clamp(0.0, 1.0);
    let v = 4.0 * p * (1.0 - p);
    v * v * (3.0 - 2.0 * v)
}

/// Forward travel of the swing ankle as a fraction of the step: a minimum-jerk ramp over
/// `p` in [0.2, 0.8], still before and after, so the foot leaves and meets the floor
/// vertically and never scuffs.
pub fn swing_advance(p: f64) -> f64 {
    min_jerk((p - SWING_LIFT_FRACTION) / (1.0 - 2.0 * SWING_LIFT_FRACTION))
}

/// First derivative of [`min_jerk`] with respect to `p`: `30p²(1-p)²`; 0 outside [0, 1].
/// Peak 15/8 at p = 1/2: a phase of duration T moving a distance D peaks at 1.875 D/T.
pub fn min_jerk_rate(p: f64) -> f64 {
    if !(0.0..=1.0).contains(&p) {
        return 0.0;
    }
    let q = p * (1.0 - p);
    30.0 * q * q
}

/// Second derivative of [`min_jerk`] with respect to `p`: `60p - 180p² + 120p³`; 0 outside
/// [0, 1]. Peaks ±10/√3 (±5.774) at p = 1/2 ∓ √3/6: a phase of duration T moving a distance
/// D accelerates at most 5.774 D/T².
pub fn min_jerk_accel(p: f64) -> f64 {
    if !(0.0..=1.0).contains(&p) {
        return 0.0;
    }
    p * (60.0 + p * (-180.0 + 120.0 * p))
}

/// Integral of [`min_jerk`] from 0 to `p`: `p⁴(5/2 - 3p + p²)` on [0, 1] (1/2 at p = 1),
/// then growing by 1 per unit of `p` (the ramp stays at 1); 0 for `p <= 0`. A rate that
/// ramps from 0 to 1 over T covers `T·min_jerk_integral(t/T)`: half the ramp's time.
///
/// ```
/// use gait_planner::trajectory::min_jerk_integral;
/// assert_eq!(min_jerk_integral(0.0), 0.0);
/// assert_eq!(min_jerk_integral(1.0), 0.5);
/// assert_eq!(min_jerk_integral(3.0), 2.5);
/// ```
pub fn min_jerk_integral(p: f64) -> f64 {
    if p <= 0.0 {
        0.0
    } else if p >= 1.0 {
        0.5 + (p - 1.0)
    } else {
        p * p * p * p * (2.5 + p * (-3.0 + p))
    }
}
