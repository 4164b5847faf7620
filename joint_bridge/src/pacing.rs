//! When a joint bridge on the monotonic clock ticks. Pure: times in, times out (s, on the
//! node's own time line).
//!
//! Two timers at the same rate, the planner's and the bridge's, meet at an arbitrary phase:
//! a command then waits up to a whole period in the bridge's reader for the next tick (on
//! average half a period, 5 ms at 100 Hz, a hundred times the DDS hop that brought it), and
//! when the phase sits near a tick, the arrival jitter puts two commands in one tick and none
//! in the next (a step of the joints skipped, then doubled). With commands driving the ticks
//! (`on_command`), each command is acted on as it comes, as the lockstep simulator's ticks
//! are: one tick per command, its latency the hop's.
//!
//! - A command ticks at once, unless the last tick was less than half a period ago: then at
//!   that half period (a sender faster than twice the rate does not drive the servo bus
//!   faster than that; a command that came early after a late one is not held long).
//! - Without commands the bridge ticks by itself, a period apart on a drift-free schedule
//!   (holding, its watchdog, `joint_states` at the rate); after a tick a command drove, its
//!   own next tick waits one and a half periods, so a command a little late still drives its
//!   tick rather than being one tick behind.
//! - Without `on_command`, only its own ticks: the fixed-rate loop.

/// When the next tick is: the bridge's own, or one a command drives.
#[derive(Debug, Clone, PartialEq)]
pub struct TickPacing {
    period_s: f64,
    on_command: bool,
    /// When the last tick ran (s).
    last_tick_s: Option<f64>,
    /// When the bridge's own next tick is due (s).
    own_due_s: f64,
}

impl TickPacing {
    /// Ticks at `rate_hz` (finite, positive) from `start_s`, the first at `start_s`; with
    /// `on_command`, commands drive the ticks as they come.
    pub fn new(rate_hz: f64, on_command: bool, start_s: f64) -> Self {
        Self {
            period_s: 1.0 / rate_hz,
            on_command,
            last_tick_s: None,
            own_due_s: start_s,
        }
    }

    /// When the bridge ticks by itself if no command comes first (s).
    pub fn own_tick_due_s(&self) -> f64 {
        self.own_due_s
    }

    /// From when a command that comes ticks (s): at once from then, held until then before
    /// (infinite without `on_command`: commands wait for the bridge's own tick).
    pub fn command_tick_from_s(&self) -> f64 {
        if !self.on_command {
            return f64::INFINITY;
        }
        self.last_tick_s
            .map_or(f64::NEG_INFINITY, |t| t + 0.5 * self.period_s)
    }

    /// A tick ran at `t_s`, driven by a command or not.
    pub fn ticked(&mut self, t_s: f64, by_command: bool) {
        self.last_tick_s = Some(t_s);
        self.own_due_s = if by_command {
            t_s + 1.5 * self.period_s
        } else {
            // On the schedule; a tick missed whole (a stall) starts it again from now.
            let next = self.own_due_s + self.period_s;
            if next > t_s {
                next
            } else {
                t_s + self.period_s
            }
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-12
    }

    #[test]
    fn without_commands_the_ticks_keep_a_drift_free_schedule() {
        // 100 Hz from t = 2 s: due 2.00, 2.01, 2.02 ... whatever the lateness of each tick.
        let mut p = TickPacing::new(100.0, true, 2.0);
        assert!(close(p.own_tick_due_s(), 2.0));
        p.ticked(2.0003, false);
        assert!(close(p.own_tick_due_s(), 2.01));
        p.ticked(2.0109, false);
        assert!(close(p.own_tick_due_s(), 2.02));
        // A stall past a whole tick: the schedule starts again from the late tick.
        p.ticked(2.047, false);
        assert!(close(p.own_tick_due_s(), 2.057));
    }

    #[test]
    fn a_command_ticks_at_once_and_moves_the_own_tick_a_period_and_a_half_on() {
        let mut p = TickPacing::new(100.0, true, 0.0);
        // Before any tick a command ticks at once.
        assert_eq!(p.command_tick_from_s(), f64::NEG_INFINITY);
        p.ticked(0.0, false);
        // Half a period after the last tick, commands tick at once.
        assert!(close(p.command_tick_from_s(), 0.005));
        // A command 3 ms after an own tick (the planner's phase): it ticks at 0.003, and the
        // own tick due at 0.01 moves to 0.003 + 0.015.
        p.ticked(0.003, true);
        assert!(close(p.own_tick_due_s(), 0.018));
        assert!(close(p.command_tick_from_s(), 0.008));
        // The next command 10 ms later ticks at once again: the bridge follows the sender.
        p.ticked(0.013, true);
        assert!(close(p.own_tick_due_s(), 0.028));
        // The sender stops: the own ticks take over, a period apart from the first.
        p.ticked(0.028, false);
        assert!(close(p.own_tick_due_s(), 0.038));
    }

    #[test]
    fn a_command_right_after_a_tick_waits_for_half_a_period() {
        // 50 Hz: a command 4 ms after the last tick is held until 10 ms after it, so a
        // sender at 1 kHz drives the bus at 100 Hz at most.
        let mut p = TickPacing::new(50.0, true, 0.0);
        p.ticked(1.0, true);
        assert!(close(p.command_tick_from_s(), 1.01));
        assert!(close(p.own_tick_due_s(), 1.03));
    }

    #[test]
    fn without_on_command_commands_wait_for_the_own_tick() {
        let mut p = TickPacing::new(100.0, false, 0.0);
        assert_eq!(p.command_tick_from_s(), f64::INFINITY);
        p.ticked(0.0, false);
        assert_eq!(p.command_tick_from_s(), f64::INFINITY);
        assert!(close(p.own_tick_due_s(), 0.01));
    }
}
