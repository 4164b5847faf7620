//! Pausing a walk anywhere, and going on: the walk's clock slows to a stop along the plan
//! and speeds up again, so the robot comes to rest on its planned path.
//!
//! Freezing the targets of a moving robot stops its joints in one servo period: the body's
//! momentum then has nowhere to go but into the soles, which rock or slide (measured: a
//! 0.72 s CoM shift of the default robot frozen at its peak speed topples it). A pause here
//! instead scales time: the plan's clock runs at a rate `r` that falls from 1 to 0 as a
//! minimum-jerk ramp over the brake time `T_b` (and rises the same way on resume). Every
//! pose passed is a planned one (the CoM over its polygon with the plan's margin, the swing
//! foot on its path, which meets the floor vertically), so only the ZMP changes: with the
//! CoM at `c(τ)` of plan time `τ(t)`, `τ' = r`,
//!
//! ```text
//! c'' = c_ττ · r² + c_τ · r'      r' = ∓ min_jerk_rate(t / T_b) / T_b
//! ```
//!
//! The first term is the plan's own acceleration, slowed; the second is the braking. The
//! ZMP `c - z/g · c''` must keep the plan's ZMP margin. For a planned tick and a point `u`
//! of the ramp the ZMP is `p0 + (1/T_b)·e`, a straight line in `1/T_b`, so the margin bounds
//! `1/T_b` per polygon edge in closed form ([`crate::timing::quadratic_scale_limit`]). Every tick
//! of the plan is reached at every point of some ramp (a pause starting a little earlier),
//! so checking every (tick, u) pair checks every pause; [`shortest_brake_s`] gives the
//! shortest brake time that keeps the margin through all of them.
//!
//! The brake covers half its time of plan time (`∫(1 - min_jerk) = 1/2`): a pause with
//! `T_b` = 0.3 s comes to rest 0.15 s of plan further on, and a pause and resume cost
//! exactly the wall time between the two calls (see [`PlanClock`]).

use ik_solver::support::Xy;
use nalgebra::{Point3, Vector3};

use crate::timing::{Edges, quadratic_scale_limit_on};
use crate::trajectory::{min_jerk, min_jerk_integral, min_jerk_rate};
use crate::zmp::{GRAVITY_M_S2, cart_table_zmp};

/// A tick that moves the plan time on by less than this (plan ticks) leaves it where it was:
/// rounding, not motion. The last tick of an n-tick brake moves it on by about 2.5/n³ ticks:
/// more than this up to 1000-tick brakes (10 s at 100 Hz); a longer one comes to rest a tick
/// sooner, by less than a nanotick.
pub const REST_TICKS: f64 = 1e-9;

/// Points per ramp at which [`shortest_brake_s`] checks the ZMP (u = 0, 1/N, ..., 1).
pub const RAMP_POINTS: usize = 40;

/// The walk's clock, in control ticks: how much plan time the ticks so far have lost to
/// pauses (and to freezes, when the joint bridge holds). The plan time of control tick `k` is
/// `(k - lost_ticks) / rate`. Whole-tick losses stay exact integers, so a walk never paused
/// is planned at exactly `k / rate`, tick for tick as the offline plan.
///
/// ```
/// use gait_planner::pause::PlanClock;
/// // A 4-tick brake: the plan advances 1 - min_jerk over each tick, half the brake in all.
/// let mut c = PlanClock::new(4);
/// assert_eq!(c.tick(false), 0.0);
/// assert!(!c.pausing());
/// c.pause();
/// assert!(c.pausing());
/// for _ in 0..4 {
///     c.tick(false);
/// }
/// assert!((c.lost_ticks() - 2.0).abs() < 1e-12);
/// assert_eq!(c.rate(), 0.0);
/// c.tick(false); // at rest: every tick is lost
/// assert!((c.lost_ticks() - 3.0).abs() < 1e-12);
/// c.resume();
/// assert!(!c.pausing());
/// for _ in 0..5 {
///     c.tick(false);
/// }
/// // A pause and resume lose exactly the ticks from pause to resume: 5.
/// assert_eq!(c.lost_ticks(), 5.0);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct PlanClock {
    brake_ticks: u32,
    /// The ramp in progress: rate from `from` to `to`, `elapsed` ticks into it.
    from: f64,
    to: f64,
    elapsed_ticks: f64,
    lost_ticks: f64,
    /// The plan time of the last tick (plan ticks), which the next never goes below.
    last_plan_ticks: f64,
}

impl PlanClock {
    /// Running at full rate, nothing lost; pauses brake over `brake_ticks` ticks (0: at once).
    pub fn new(brake_ticks: u32) -> Self {
        Self {
            brake_ticks,
            from: 1.0,
            to: 1.0,
            elapsed_ticks: f64::INFINITY,
            lost_ticks: 0.0,
            last_plan_ticks: f64::NEG_INFINITY,
        }
    }

    /// The brake time of the pauses and resumes to come (ticks).
    pub fn set_brake_ticks(&mut self, brake_ticks: u32) {
        self.brake_ticks = brake_ticks;
    }

    /// The brake time (ticks).
    pub fn brake_ticks(&self) -> u32 {
        self.brake_ticks
    }

    /// Starts slowing to a stop. False if already paused or pausing.
    pub fn pause(&mut self) -> bool {
        self.ramp_to(0.0)
    }

    /// Starts speeding up to full rate. False if not paused or pausing.
    pub fn resume(&mut self) -> bool {
        self.ramp_to(1.0)
    }

    /// True from a pause until the next resume (slowing down or at rest).
    pub fn pausing(&self) -> bool {
        self.to == 0.0
    }

    /// True once a pause has brought the plan to rest.
    pub fn at_rest(&self) -> bool {
        self.to == 0.0 && self.rate() == 0.0
    }

    fn ramp_to(&mut self, to: f64) -> bool {
        if self.to == to {
            return false;
        }
        self.from = self.rate();
        self.to = to;
        self.elapsed_ticks = 0.0;
        true
    }

    /// How fast plan time runs now (plan ticks per tick).
    pub fn rate(&self) -> f64 {
        let u = if self.brake_ticks == 0 {
            1.0
        } else {
            self.elapsed_ticks / f64::from(self.brake_ticks)
        };
        self.from + (self.to - self.from) * min_jerk(u)
    }

    /// Plan ticks covered by the ramp from its start to `e` ticks into it.
    fn covered(&self, e: f64) -> f64 {
        let shape = if self.brake_ticks == 0 {
            e
        } else {
            let n = f64::from(self.brake_ticks);
            n * min_jerk_integral(e / n)
        };
        self.from * e + (self.to - self.from) * shape
    }

    /// One control tick: `frozen` (the joint bridge holds) loses it whole and leaves the ramp
    /// where it is. Returns the ticks lost so far.
    pub fn tick(&mut self, frozen: bool) -> f64 {
        if frozen {
            self.lost_ticks += 1.0;
            return self.lost_ticks;
        }
        if self.elapsed_ticks.is_finite() {
            let e = self.elapsed_ticks;
            self.lost_ticks += 1.0 - (self.covered(e + 1.0) - self.covered(e));
            self.elapsed_ticks += 1.0;
            if self.to == 1.0 && self.elapsed_ticks >= f64::from(self.brake_ticks) {
                self.elapsed_ticks = f64::INFINITY;
                self.from = 1.0;
            }
        } else if self.to == 0.0 {
            self.lost_ticks += 1.0;
        } else {
            // At full rate: a whole pause lost whole ticks; drop the rounding of the ramps'
            // sums (this tick moves the plan a whole tick on, so its time still grows).
            let whole = self.lost_ticks.round();
            if (self.lost_ticks - whole).abs() < 1e-6 {
                self.lost_ticks = whole;
            }
        }
        self.lost_ticks
    }

    /// The ticks lost so far.
    pub fn lost_ticks(&self) -> f64 {
        self.lost_ticks
    }

    /// [`Self::tick`] for control tick `k`: its plan time in plan ticks, `k - lost`, never
    /// below the last one's (the sums of a ramp round in the last bit; a planner refuses
    /// time that runs back), and exactly the last one's when it would move on by less than
    /// [`REST_TICKS`] (at rest, paused or frozen: `k - lost` with both growing rounds
    /// differently from tick to tick). Never paused: exactly `k`.
    pub fn plan_ticks(&mut self, k: u64, frozen: bool) -> f64 {
        let lost = self.tick(frozen);
        let mut t = (k as f64 - lost).max(0.0).max(self.last_plan_ticks);
        if t - self.last_plan_ticks < REST_TICKS {
            t = self.last_plan_ticks;
        }
        self.last_plan_ticks = t;
        t
    }
}

/// One planned tick as the brake check needs it.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedCom {
    /// Whole-body CoM (m).
    pub com_m: Point3<f64>,
    /// Its velocity in plan time (m/s).
    pub velocity_m_s: Vector3<f64>,
    /// Its planned acceleration (m/s²).
    pub accel_m_s2: Vector3<f64>,
    /// The support polygon (counter-clockwise).
    pub polygon: Vec<Xy>,
}

/// Where the shortest brake is bound: the planned tick (index into the slice), the point
/// of the ramp, and whether braking or speeding up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BrakeBound {
    /// Shortest brake time keeping the margin (s); infinite when none does.
    pub brake_s: f64,
    /// The tick that needs it.
    pub tick: usize,
    /// The point of the ramp, 0 to 1.
    pub ramp: f64,
    /// True for a resume (speeding up), false for a pause.
    pub resuming: bool,
}

/// The points of a ramp [`shortest_brake_s`] checks, pause and resume: the rate `r` and its
/// change per unit of ramp time (`r'·T_b`).
pub fn ramp_points() -> impl Iterator<Item = (f64, f64)> {
    (0..=RAMP_POINTS).flat_map(|j| {
        let u = j as f64 / RAMP_POINTS as f64;
        let (s, slope) = (min_jerk(u), min_jerk_rate(u));
        [(1.0 - s, -slope), (s, slope)]
    })
}

/// The shortest brake time (s) for which pausing and resuming at any tick of `ticks` keeps
/// the ZMP at least `min_margin_m` inside the support polygon (see the module). Infinite,
/// naming the tick, when one cannot keep it at any brake time (its CoM between the planned
/// ZMP and itself is already closer).
pub fn shortest_brake_s(ticks: &[PlannedCom], min_margin_m: f64) -> BrakeBound {
    let mut worst = BrakeBound {
        brake_s: 0.0,
        tick: 0,
        ramp: 0.0,
        resuming: false,
    };
    for (i, t) in ticks.iter().enumerate() {
        let k = t.com_m.z / GRAVITY_M_S2;
        let edges = Edges::of(&t.polygon);
        for (j, (r, r_rate)) in ramp_points().enumerate() {
            let p0 = cart_table_zmp(t.com_m, t.accel_m_s2 * (r * r));
            // The braking term per 1/T_b: -z/g · c_τ · r'·T_b; the margin bounds 1/T_b.
            let e = [
                -k * t.velocity_m_s.x * r_rate,
                -k * t.velocity_m_s.y * r_rate,
            ];
            let need = 1.0 / quadratic_scale_limit_on(&edges, p0, [0.0, 0.0], e, min_margin_m);
            if need > worst.brake_s {
                worst = BrakeBound {
                    brake_s: need,
                    tick: i,
                    ramp: (j / 2) as f64 / RAMP_POINTS as f64,
                    resuming: j % 2 == 1,
                };
            }
        }
    }
    worst
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Paused (or frozen), the plan time stands exactly still, however long: the joint
    /// commands of a paused walk do not change in the last bit either (`k - lost` with both
    /// growing rounded differently from tick to tick).
    #[test]
    fn at_rest_the_plan_time_does_not_move_in_the_last_bit() {
        for (brake, from) in [(25, 337_u64), (8, 1000), (13, 45_678)] {
            let mut c = PlanClock::new(brake);
            for k in 0..from {
                c.plan_ticks(k, false);
            }
            c.pause();
            for k in from..from + u64::from(brake) + 1 {
                c.plan_ticks(k, false);
            }
            assert!(c.at_rest());
            let rest = c.plan_ticks(from + u64::from(brake) + 1, false);
            for k in from + u64::from(brake) + 2..from + 100_000 {
                let frozen = k % 7 == 0;
                assert_eq!(
                    c.plan_ticks(k, frozen).to_bits(),
                    rest.to_bits(),
                    "tick {k}"
                );
            }
        }
    }

    fn square(half_m: f64) -> Vec<Xy> {
        vec![
            [-half_m, -half_m],
            [half_m, -half_m],
            [half_m, half_m],
            [-half_m, half_m],
        ]
    }

    #[test]
    fn a_resting_plan_pauses_at_once() {
        let t = PlannedCom {
            com_m: Point3::new(0.0, 0.0, 0.2),
            velocity_m_s: Vector3::zeros(),
            accel_m_s2: Vector3::zeros(),
            polygon: square(0.05),
        };
        assert_eq!(shortest_brake_s(&[t], 0.01).brake_s, 0.0);
    }

    #[test]
    fn a_cruising_com_brakes_within_the_margin_worked_by_hand() {
        // CoM 0.2 m up at the centre of a 0.1 m square, moving 0.1 m/s in +x, no planned
        // acceleration. Braking, the ZMP moves ahead by z/g · v · 1.875 / T_b at the ramp's
        // middle; 0.04 m of room (0.05 - 0.01 margin) gives T_b = 0.2 · 0.1 · 1.875 /
        // (9.80665 · 0.04).
        let t = PlannedCom {
            com_m: Point3::new(0.0, 0.0, 0.2),
            velocity_m_s: Vector3::new(0.1, 0.0, 0.0),
            accel_m_s2: Vector3::zeros(),
            polygon: square(0.05),
        };
        let b = shortest_brake_s(&[t], 0.01);
        let want = 0.2 * 0.1 * 1.875 / (GRAVITY_M_S2 * 0.04);
        assert!((b.brake_s - want).abs() < 1e-12, "{} vs {want}", b.brake_s);
        assert_eq!(b.ramp, 0.5);
    }

    #[test]
    fn a_com_already_closer_than_the_margin_cannot_pause() {
        let t = PlannedCom {
            com_m: Point3::new(0.045, 0.0, 0.2),
            velocity_m_s: Vector3::new(0.1, 0.0, 0.0),
            accel_m_s2: Vector3::zeros(),
            polygon: square(0.05),
        };
        assert!(shortest_brake_s(&[t], 0.01).brake_s.is_infinite());
    }

    #[test]
    fn a_freeze_loses_whole_ticks_and_holds_the_ramp() {
        let mut c = PlanClock::new(0);
        c.tick(false);
        assert_eq!(c.lost_ticks(), 0.0);
        c.tick(true);
        c.tick(true);
        assert_eq!(c.lost_ticks(), 2.0);
        // Brake time 0: a pause stops at once, a resume goes on at once.
        c.pause();
        c.tick(false);
        assert_eq!(c.lost_ticks(), 3.0);
        c.resume();
        c.tick(false);
        assert_eq!(c.lost_ticks(), 3.0);
    }

    #[test]
    fn a_resume_before_the_stop_speeds_up_from_where_the_brake_was() {
        let mut c = PlanClock::new(10);
        c.pause();
        for _ in 0..5 {
            c.tick(false);
        }
        let r = c.rate();
        assert!((r - 0.5).abs() < 1e-12, "{r}");
        assert!(c.resume());
        assert!(!c.resume(), "resumed twice");
        c.tick(false);
        assert!(c.rate() > r);
        for _ in 0..10 {
            c.tick(false);
        }
        assert_eq!(c.rate(), 1.0);
        // The plan time never ran backwards nor faster than the ticks.
        let lost = c.lost_ticks();
        assert!(lost > 0.0 && lost < 16.0, "{lost}");
    }
}
