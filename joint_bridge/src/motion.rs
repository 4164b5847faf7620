//! The one motion limiter every joint output goes through: a velocity and an acceleration
//! limit per joint, braking in time to stop at the goal, with the step's dt bounded. Pure:
//! positions and time in, positions out.
//!
//! Each tick picks the joint's new velocity `v'` so that
//!
//! - `|v'| <= v_max` and `|v' - v| <= a_max * dt` (`v` the previous tick's velocity), always;
//! - `v'` is the goal's own velocity (how far the goal moved since the last tick, when that
//!   is within `v_max`: a trajectory is followed without lag; a longer jump is a new goal)
//!   plus a closing speed towards where the goal was, no faster than the speed from which braking at `a_max`, tick by tick, stops
//!   there, and no faster than closing the gap in this tick. A goal that jumps is approached
//!   and stopped at without overshoot, unless the limiter was already moving too fast
//!   towards it.
//!
//! Then `x' = x + v' dt`. The realised velocity and acceleration are exactly `v'` and
//! `(v' - v) / dt`: no step of the output ever exceeds the limits. A jump of the goal, a
//! new command source, a resume after a hold: all become a smooth move.
//!
//! The ticks to come may be shorter than this one (a control loop that stalled, then runs at
//! its rate again): a tick longer than the shortest seen so far also keeps its speed low
//! enough to brake from in ticks that short after it, so a stall never gains a speed the
//! loop cannot stop from (found by the bench-time run of the bridge's property test: a
//! stall near a joint limit, then a stop 27 rad/s² hard).

/// Motion bounds of one joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionLimit {
    /// Largest speed (rad/s), finite and positive.
    pub velocity_rad_s: f64,
    /// Largest change of speed (rad/s²), positive; infinite for none.
    pub acceleration_rad_s2: f64,
}

/// Positions and velocities of the joints as last output.
#[derive(Debug, Clone, PartialEq)]
pub struct Limiter {
    position_rad: Vec<f64>,
    velocity_rad_s: Vec<f64>,
    /// The goals of the last tick (NaN before the first).
    goal_rad: Vec<f64>,
    /// The shortest tick seen (s): the length the ticks after a longer one may have.
    shortest_tick_s: f64,
}

impl Limiter {
    /// At rest at these positions.
    pub fn at_rest(position_rad: &[f64]) -> Self {
        Self {
            position_rad: position_rad.to_vec(),
            velocity_rad_s: vec![0.0; position_rad.len()],
            goal_rad: vec![f64::NAN; position_rad.len()],
            shortest_tick_s: f64::INFINITY,
        }
    }

    /// Starts again at rest from these positions (a measured pose after the torque was off
    /// or the device was away: the joints are where they are, not where they were sent).
    pub fn reset(&mut self, position_rad: &[f64]) {
        self.position_rad.copy_from_slice(position_rad);
        self.velocity_rad_s.fill(0.0);
        self.goal_rad.fill(f64::NAN);
    }

    /// The positions last output (rad).
    pub fn position_rad(&self) -> &[f64] {
        &self.position_rad
    }

    /// The velocities of the last step (rad/s).
    pub fn velocity_rad_s(&self) -> &[f64] {
        &self.velocity_rad_s
    }

    /// Where each joint comes to rest braking at its acceleration limit from now: the goal
    /// of a hold, so holding never turns a joint back.
    pub fn stopping_point_rad(&self, limits: &[MotionLimit]) -> Vec<f64> {
        self.position_rad
            .iter()
            .zip(&self.velocity_rad_s)
            .zip(limits)
            .map(|((&x, &v), lim)| {
                if lim.acceleration_rad_s2.is_finite() {
                    x + v * v.abs() / (2.0 * lim.acceleration_rad_s2)
                } else {
                    x
                }
            })
            .collect()
    }

    /// One tick of `dt_s` towards the goals; non-finite goals and `dt_s <= 0` keep the
    /// joint where it is (a zero-length tick moves nothing).
    pub fn step(&mut self, goal_rad: &[f64], limits: &[MotionLimit], dt_s: f64) {
        if dt_s > 0.0 && dt_s.is_finite() {
            self.shortest_tick_s = self.shortest_tick_s.min(dt_s);
        }
        let next_tick_s = self.shortest_tick_s;
        for (((x, v), last), (&goal, lim)) in self
            .position_rad
            .iter_mut()
            .zip(self.velocity_rad_s.iter_mut())
            .zip(self.goal_rad.iter_mut())
            .zip(goal_rad.iter().zip(limits))
        {
            if !(dt_s > 0.0 && dt_s.is_finite() && goal.is_finite()) {
                continue;
            }
            (*x, *v) = step_one(*x, *v, *last, goal, lim, dt_s, next_tick_s);
            *last = goal;
        }
    }
}

/// The largest speed from which braking by `a dt` per tick, `dt` per tick, covers at most
/// `distance` (exact for the discrete braking sequence v, v - a dt, ..., down to 0).
fn braking_speed(distance: f64, a: f64, dt: f64) -> f64 {
    if !a.is_finite() {
        return f64::INFINITY;
    }
    // In units of a dt²: the sequence from k a dt covers ceil(k) terms of (k - i) a dt².
    let d = distance / (a * dt * dt);
    // Whole ticks n with n (n + 1) / 2 <= d, then the fraction in the next one.
    let n = (((1.0 + 8.0 * d).sqrt() - 1.0) / 2.0).floor().max(0.0);
    let k = d / (n + 1.0) + n / 2.0;
    a * dt * k
}

/// Distance covered after this tick braking from `v` by `a h` per tick of `h`:
/// (v - a h) h + (v - 2 a h) h + ... while positive.
fn braking_distance_after(v: f64, a: f64, h: f64) -> f64 {
    let m = (v / (a * h)).floor();
    h * (m * v - a * h * m * (m + 1.0) / 2.0)
}

/// The largest speed for a tick of `dt` followed by ticks of `h < dt` such that this tick
/// and the braking after it cover at most `distance` (bisection: the covered distance grows
/// with the speed).
fn braking_speed_before_shorter_ticks(distance: f64, a: f64, dt: f64, h: f64) -> f64 {
    let covered = |v: f64| v * dt + braking_distance_after(v, a, h);
    let (mut lo, mut hi) = (0.0, distance / dt);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if covered(mid) <= distance {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// One joint, one tick of `dt`, the ticks after it possibly as short as `next_dt`:
/// `last_goal` is the previous tick's goal (NaN: none).
fn step_one(
    x: f64,
    v: f64,
    last_goal: f64,
    goal: f64,
    lim: &MotionLimit,
    dt: f64,
    next_dt: f64,
) -> (f64, f64) {
    let vmax = lim.velocity_rad_s;
    // The goal's own motion over this tick, if it is one the joint can follow (a jump
    // further than the velocity limit allows is a new goal to go to, not a motion), and the
    // gap to where the goal was.
    let moved = goal - last_goal;
    let goal_v = if moved.abs() <= vmax * dt {
        moved / dt
    } else {
        0.0
    };
    let gap = goal - goal_v * dt - x;
    let a = lim.acceleration_rad_s2;
    let braking = if next_dt < dt && a.is_finite() {
        braking_speed_before_shorter_ticks(gap.abs(), a, dt, next_dt)
    } else {
        braking_speed(gap.abs(), a, dt)
    };
    let closing = vmax.min(gap.abs() / dt).min(braking);
    let wanted = goal_v + gap.signum() * closing;
    let dv = lim.acceleration_rad_s2 * dt;
    let v_new = if dv.is_finite() {
        wanted.clamp(v - dv, v + dv)
    } else {
        wanted
    }
    .clamp(-vmax, vmax);
    (x + v_new * dt, v_new)
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIM: MotionLimit = MotionLimit {
        velocity_rad_s: 2.0,
        acceleration_rad_s2: 10.0,
    };

    #[test]
    fn from_rest_the_first_ticks_accelerate_at_the_limit() {
        // 10 rad/s² for 0.01 s: 0.1 rad/s, then 0.2 rad/s; positions 0.001, 0.003 rad.
        let mut l = Limiter::at_rest(&[0.0]);
        l.step(&[1.0], &[LIM], 0.01);
        assert!((l.velocity_rad_s()[0] - 0.1).abs() < 1e-12);
        assert!((l.position_rad()[0] - 0.001).abs() < 1e-12);
        l.step(&[1.0], &[LIM], 0.01);
        assert!((l.position_rad()[0] - 0.003).abs() < 1e-12);
    }

    #[test]
    fn after_a_stalled_tick_the_short_ticks_still_brake_within_the_limit() {
        // Moving towards 1.0 in 10 ms ticks, a 50 ms tick (the loop stalled) at any point
        // of the move, then 10 ms ticks again: no speed change ever exceeds 10 rad/s² x the
        // tick, and the joint stops on the goal without passing it.
        for stall_at in 0..80 {
            let mut l = Limiter::at_rest(&[0.0]);
            let mut ticks = vec![0.01; stall_at];
            ticks.push(0.05);
            ticks.extend([0.01; 200]);
            for (k, dt) in ticks.into_iter().enumerate() {
                let v0 = l.velocity_rad_s()[0];
                l.step(&[1.0], &[LIM], dt);
                let v = l.velocity_rad_s()[0];
                let at = format!("stall at tick {stall_at}, tick {k}");
                assert!(
                    (v - v0).abs() <= 10.0 * dt + 1e-9,
                    "{at}: {v0} -> {v} in {dt} s"
                );
                assert!(l.position_rad()[0] <= 1.0 + 1e-12, "{at}: passed the goal");
            }
            assert!(
                (l.position_rad()[0] - 1.0).abs() < 1e-9,
                "stall at tick {stall_at}"
            );
        }
    }

    #[test]
    fn a_long_move_cruises_at_the_velocity_limit_and_stops_on_the_goal() {
        let mut l = Limiter::at_rest(&[0.0]);
        let mut top = 0.0f64;
        for _ in 0..300 {
            l.step(&[1.0], &[LIM], 0.01);
            top = top.max(l.velocity_rad_s()[0]);
            assert!(l.position_rad()[0] <= 1.0 + 1e-12, "overshot");
        }
        assert!((top - 2.0).abs() < 1e-12, "{top}");
        assert!((l.position_rad()[0] - 1.0).abs() < 1e-12);
        assert_eq!(l.velocity_rad_s()[0], 0.0);
    }

    #[test]
    fn braking_speed_is_exact_for_the_discrete_sequence() {
        // From 3 a dt: 3 + 2 + 1 = 6 a dt² covered.
        let (a, dt) = (10.0, 0.01);
        let v = braking_speed(6.0 * a * dt * dt, a, dt);
        assert!((v - 3.0 * a * dt).abs() < 1e-12, "{v}");
        // Half a tick more distance: the speed grows by half of d / (n + 1).
        let v = braking_speed(6.5 * a * dt * dt, a, dt);
        assert!((v - (3.0 + 0.5 / 4.0) * a * dt).abs() < 1e-12, "{v}");
    }

    #[test]
    fn a_reversed_goal_brakes_within_the_acceleration_limit() {
        let mut l = Limiter::at_rest(&[0.0]);
        for _ in 0..50 {
            l.step(&[1.0], &[LIM], 0.01);
        }
        let v0 = l.velocity_rad_s()[0];
        assert!(v0 > 1.0);
        l.step(&[0.0], &[LIM], 0.01);
        let v1 = l.velocity_rad_s()[0];
        assert!((v0 - v1 - 0.1).abs() < 1e-12, "{v0} -> {v1}");
    }

    #[test]
    fn no_time_or_a_non_finite_goal_moves_nothing() {
        let mut l = Limiter::at_rest(&[0.5]);
        l.step(&[1.0], &[LIM], 0.0);
        l.step(&[f64::NAN], &[LIM], 0.01);
        l.step(&[1.0], &[LIM], f64::NAN);
        assert_eq!(l.position_rad(), [0.5]);
    }

    #[test]
    fn without_an_acceleration_limit_it_is_a_velocity_limit() {
        let free = MotionLimit {
            velocity_rad_s: 1.0,
            acceleration_rad_s2: f64::INFINITY,
        };
        let mut l = Limiter::at_rest(&[0.0]);
        l.step(&[0.5], &[free], 0.1);
        assert!((l.position_rad()[0] - 0.1).abs() < 1e-12);
        l.step(&[0.15], &[free], 0.1);
        assert!((l.position_rad()[0] - 0.15).abs() < 1e-12);
    }
}
