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
//!   own next tick waits one and a half periods while the commands come about a period
//!   apart, so a command a little late still drives its tick rather than being one tick
//!   behind; when they come further apart (a sender at half the rate, a single command), a
//!   period: the own ticks fill in between on the bridge's grid, except within half a period
//!   of when the sender's next command is due (its last one plus the time between its last
//!   two), where the command drives the tick and the own one waits half a period past it (a
//!   sender at 50 Hz and a bridge at 100 Hz tick every 10 ms, every other tick a command's).
//! - Without `on_command`, only its own ticks: the fixed-rate loop.

/// When the next tick is: the bridge's own, or one a command drives.
#[derive(Debug, Clone, PartialEq)]
pub struct TickPacing {
    period_s: f64,
    on_command: bool,
    /// When the last tick ran (s).
    last_tick_s: Option<f64>,
    /// When the last tick a command drove ran (s).
    last_command_tick_s: Option<f64>,
    /// The time between the last two ticks commands drove (s).
    command_apart_s: Option<f64>,
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
            last_command_tick_s: None,
            command_apart_s: None,
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
        let next = if by_command {
            // The commands' own period, from the last two (unknown at the first: taken as
            // the bridge's).
            self.command_apart_s = self.last_command_tick_s.map(|c| t_s - c);
            self.last_command_tick_s = Some(t_s);
            if self
                .command_apart_s
                .is_some_and(|d| d >= 1.25 * self.period_s)
            {
                t_s + self.period_s
            } else {
                t_s + 1.5 * self.period_s
            }
        } else {
            // On the schedule; a tick missed whole (a stall) starts it again from now.
            let next = self.own_due_s + self.period_s;
            if next > t_s {
                next
            } else {
                t_s + self.period_s
            }
        };
        self.own_due_s = self.clear_of_the_next_command(next);
    }

    /// `own_s`, or half a period past the sender's next command when that is due within
    /// half a period of `own_s` (a sender slower than 1.25 periods, on its own schedule).
    fn clear_of_the_next_command(&self, own_s: f64) -> f64 {
        let half = 0.5 * self.period_s;
        match (self.last_command_tick_s, self.command_apart_s) {
            (Some(c), Some(d)) if d >= 2.5 * half => {
                let m = ((own_s - half - c) / d).ceil().max(1.0);
                let due = c + m * d;
                if (own_s - due).abs() < half {
                    due + half
                } else {
                    own_s
                }
            }
            _ => own_s,
        }
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
    fn a_sender_at_half_the_rate_gets_the_own_ticks_in_between_on_the_grid() {
        // Commands every 20 ms to a 100 Hz bridge: after the second command tick the own
        // tick comes a period later, and the next command, a period after that, ticks at
        // once: 0.100, 0.110, 0.1202, 0.1302 ...
        let mut p = TickPacing::new(100.0, true, 0.0);
        p.ticked(0.080, true);
        assert!(close(p.own_tick_due_s(), 0.095));
        p.ticked(0.095, false);
        p.ticked(0.100, true);
        assert!(close(p.own_tick_due_s(), 0.110));
        p.ticked(0.110, false);
        // The grid's 0.120 is when the next command is due: the command drives it (from
        // 0.115 on), the own tick waits until 0.125 in case it does not come.
        assert!(close(p.command_tick_from_s(), 0.115));
        assert!(close(p.own_tick_due_s(), 0.125));
        p.ticked(0.1202, true);
        assert!(close(p.own_tick_due_s(), 0.1302));
        // The command due at 0.1404 does not come: the own tick waits until 0.1454, then
        // goes on a period apart, clear of the next command due (0.1606: until 0.1656).
        p.ticked(0.1302, false);
        assert!(close(p.own_tick_due_s(), 0.1454));
        p.ticked(0.1454, false);
        assert!(close(p.own_tick_due_s(), 0.1554));
        p.ticked(0.1554, false);
        assert!(close(p.own_tick_due_s(), 0.1656));
        // A sender at 77 Hz (13 ms apart): no own tick between its commands (the grid's
        // 1.023 is within half a period of the command due at 1.026: it waits until 1.031).
        let mut r = TickPacing::new(100.0, true, 0.0);
        r.ticked(1.0, true);
        r.ticked(1.013, true);
        assert!(close(r.own_tick_due_s(), 1.031));
        // A single command after a long silence: the own ticks go on a period after it.
        let mut q = TickPacing::new(100.0, true, 0.0);
        q.ticked(1.0, true);
        q.ticked(1.015, false);
        q.ticked(7.0, true);
        assert!(close(q.own_tick_due_s(), 7.01));
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
