//! What `biped walk` records from the fleet, keyed by the messages' stamps (simulated time,
//! ns): every publisher stamps tick t with t, so the streams line up exactly.

use std::collections::BTreeMap;

use biped_msgs::msg::{
    GaitPhase, JointState, PointStamped, PolygonStamped, PoseStamped, StringMsg,
};
use gait_planner::PhaseKind;
use nalgebra::Isometry3;
use ros2_client::Subscription;

/// The planner's phase at a tick.
#[derive(Debug, Clone, PartialEq)]
pub struct PhaseAt {
    /// The phase.
    pub kind: PhaseKind,
    /// The swing number.
    pub step_index: u32,
}

/// Everything recorded, by stamp (ns).
#[derive(Debug, Default)]
pub struct Recording {
    /// Newest `/clock` value (ns).
    pub clock_ns: i64,
    /// The planner's phase per tick (`insert_phase` adds to it, keeping `walk`).
    phases: BTreeMap<i64, PhaseAt>,
    /// The walk's first non-idle tick and the first idle tick after it, kept as phases come
    /// (`biped walk` asks for them at every message: a scan each time grew with the walk).
    walk: WalkSpan,
    /// The commanded leg joints per tick (ik_solver's `joint_commands`): name → rad.
    pub commands: BTreeMap<i64, Vec<(String, f64)>>,
    /// Measured joint positions per tick (sim_bridge's `joint_states`).
    pub states: BTreeMap<i64, JointState>,
    /// Ground-truth base pose per tick.
    pub base: BTreeMap<i64, Isometry3<f64>>,
    /// Centre of pressure per tick (world x, y, m).
    pub cop: BTreeMap<i64, [f64; 2]>,
    /// Support polygon per tick (world x, y, m).
    pub support: BTreeMap<i64, Vec<[f64; 2]>>,
    /// The fall report, if any: when it happened (ns; the simulator's `t = ... s`, else the
    /// clock when the report came) and the report.
    pub fall: Option<(i64, String)>,
    /// Messages that could not be read, by topic.
    pub unreadable: BTreeMap<&'static str, u64>,
    /// The stops asked (`--estop-at` or `--pause-at`), in order.
    pub stops: Vec<StopEvent>,
}

/// One stop of a walk (an e-stop or a pause): when it was asked, answered and released, by
/// the clock (ns).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StopEvent {
    /// `~/estop` (or `~/pause` true) sent.
    pub requested_ns: i64,
    /// Its answer came (the bridge holds, or the planner brakes, by then).
    pub answered_ns: Option<i64>,
    /// `~/reset` (or `~/pause` false) answered.
    pub reset_ns: Option<i64>,
}

/// Where the walk starts and ends in the phases recorded so far.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
struct WalkSpan {
    start_ns: Option<i64>,
    end_ns: Option<i64>,
}

impl WalkSpan {
    /// Found by a scan of every phase: the first non-idle one, then the first idle one after.
    fn scan(phases: &BTreeMap<i64, PhaseAt>) -> Self {
        let start_ns = phases
            .iter()
            .find(|(_, p)| p.kind != PhaseKind::Idle)
            .map(|(&t, _)| t);
        let end_ns = start_ns.and_then(|s| {
            phases
                .range(s..)
                .find(|(_, p)| p.kind == PhaseKind::Idle)
                .map(|(&t, _)| t)
        });
        Self { start_ns, end_ns }
    }

    /// After `idle` (or not) was recorded at `t_ns`, over `was` (what that tick held
    /// before, if anything): the span. A phase after every other one (how one publisher's
    /// phases come) or a tick said again as it was moves it in O(1); anything else (out of
    /// order, a tick said again otherwise) scans again.
    fn after_insert(
        self,
        phases: &BTreeMap<i64, PhaseAt>,
        t_ns: i64,
        idle: bool,
        was: Option<bool>,
    ) -> Self {
        if was == Some(idle) {
            return self;
        }
        let newest = was.is_none() && phases.last_key_value().is_some_and(|(&t, _)| t == t_ns);
        if !newest {
            return Self::scan(phases);
        }
        match (self.start_ns, self.end_ns, idle) {
            (None, _, false) => Self {
                start_ns: Some(t_ns),
                end_ns: None,
            },
            (Some(s), None, true) => Self {
                start_ns: Some(s),
                end_ns: Some(t_ns),
            },
            _ => self,
        }
    }
}

fn drain<M: serde::de::DeserializeOwned + 'static>(
    sub: &Subscription<M>,
    topic: &'static str,
    unreadable: &mut BTreeMap<&'static str, u64>,
    mut f: impl FnMut(M),
) {
    loop {
        match sub.take() {
            Ok(Some((m, _))) => f(m),
            Ok(None) => break,
            Err(_) => *unreadable.entry(topic).or_default() += 1,
        }
    }
}

/// The time in sim_bridge's fall report ("the robot fell at t = 4.001 s: ..."), ns.
fn fall_time_ns(report: &str) -> Option<i64> {
    let rest = report.split("t = ").nth(1)?;
    let secs: f64 = rest.split(" s").next()?.trim().parse().ok()?;
    secs.is_finite().then(|| (secs * 1e9).round() as i64)
}

impl Recording {
    /// Takes every message waiting.
    #[allow(clippy::too_many_arguments)]
    pub fn drain(
        &mut self,
        phase: &Subscription<GaitPhase>,
        commands: &Subscription<JointState>,
        states: &Subscription<JointState>,
        base: &Subscription<PoseStamped>,
        cop: &Subscription<PointStamped>,
        support: &Subscription<PolygonStamped>,
        fall: &Subscription<StringMsg>,
    ) {
        let u = &mut self.unreadable;
        let mut phases = Vec::new();
        drain(phase, "gait/phase", u, |m| {
            if let Ok(kind) = m.phase.parse::<PhaseKind>() {
                let at = PhaseAt {
                    kind,
                    step_index: m.step_index,
                };
                phases.push((m.header.stamp.to_nanos(), at));
            }
        });
        drain(commands, "joint_commands", u, |m| {
            self.commands.insert(
                m.header.stamp.to_nanos(),
                m.name.into_iter().zip(m.position).collect(),
            );
        });
        drain(states, "joint_states", u, |m| {
            self.states.insert(m.header.stamp.to_nanos(), m);
        });
        drain(base, "sim/base_pose", u, |m| {
            self.base
                .insert(m.header.stamp.to_nanos(), Isometry3::from(&m.pose));
        });
        drain(cop, "sim/cop", u, |m| {
            self.cop
                .insert(m.header.stamp.to_nanos(), [m.point.x, m.point.y]);
        });
        drain(support, "sim/support_polygon", u, |m| {
            self.support.insert(
                m.header.stamp.to_nanos(),
                m.polygon
                    .points
                    .iter()
                    .map(|p| [f64::from(p.x), f64::from(p.y)])
                    .collect(),
            );
        });
        let clock = self.clock_ns;
        drain(fall, "sim/fall", u, |m| {
            if self.fall.is_none() {
                let t = fall_time_ns(&m.data).unwrap_or(clock);
                self.fall = Some((t, m.data));
            }
        });
        for (t_ns, at) in phases {
            self.insert_phase(t_ns, at);
        }
    }

    /// Records the planner's phase at `t_ns` (a tick said again replaces what it said).
    pub fn insert_phase(&mut self, t_ns: i64, at: PhaseAt) {
        let idle = at.kind == PhaseKind::Idle;
        let was = self
            .phases
            .insert(t_ns, at)
            .map(|p| p.kind == PhaseKind::Idle);
        self.walk = self.walk.after_insert(&self.phases, t_ns, idle, was);
    }

    /// The planner's phase per tick.
    pub fn phases(&self) -> &BTreeMap<i64, PhaseAt> {
        &self.phases
    }

    /// The first tick of the walk (the first phase other than idle), ns.
    pub fn walk_start_ns(&self) -> Option<i64> {
        self.walk.start_ns
    }

    /// The first idle tick after the walk, ns.
    pub fn walk_end_ns(&self) -> Option<i64> {
        self.walk.end_ns
    }

    /// When the recording ends (ns): `tail_s` after the walk ended, or 0.5 s after a fall.
    /// What arrives later is not measured, so every run measures the same ticks.
    pub fn end_ns(&self, tail_s: f64) -> Option<i64> {
        if let Some((t, _)) = &self.fall {
            return Some(t + 500_000_000);
        }
        self.walk_end_ns()
            .map(|t| t + (tail_s * 1e9).round() as i64)
    }

    /// True once every stream the report measures up to `end_ns` has a sample stamped at
    /// or after it. Each publisher's samples come in order, so none before it is still on
    /// its way; the `/clock` that says the simulation got there travels on its own and can
    /// overtake them (a DDS event loop sends one writer's backlog before the next writer's).
    pub fn received_through(&self, end_ns: i64) -> bool {
        fn reached<V>(stream: &BTreeMap<i64, V>, end_ns: i64) -> bool {
            stream.last_key_value().is_some_and(|(&t, _)| t >= end_ns)
        }
        reached(&self.phases, end_ns)
            && reached(&self.commands, end_ns)
            && reached(&self.states, end_ns)
            && reached(&self.base, end_ns)
            && reached(&self.cop, end_ns)
            && reached(&self.support, end_ns)
    }

    /// One line of progress.
    pub fn progress_line(&self) -> String {
        let t = self.clock_ns as f64 * 1e-9;
        let phase = self
            .phases
            .values()
            .next_back()
            .map_or("-".to_owned(), |p| {
                format!("{} (step {})", p.kind, p.step_index)
            });
        let x = self
            .base
            .values()
            .next_back()
            .map_or(f64::NAN, |b| b.translation.x);
        format!("t = {t:6.2} s  phase {phase:24}  base x = {x:+.3} m")
    }
}

#[cfg(test)]
mod tests {
    // The recording is complete through a tick only when every measured stream has reached
    // it: the clock alone, or all streams but one, is not enough.
    #[test]
    fn a_recording_is_received_through_a_tick_once_every_stream_reached_it() {
        use super::{PhaseAt, Recording};
        use biped_msgs::msg::JointState;
        use gait_planner::PhaseKind;
        use nalgebra::Isometry3;
        let mut rec = Recording {
            clock_ns: 50,
            ..Recording::default()
        };
        assert!(!rec.received_through(30));
        for t in [10, 20, 30] {
            let idle = PhaseAt {
                kind: PhaseKind::Idle,
                step_index: 0,
            };
            rec.insert_phase(t, idle);
            rec.commands.insert(t, Vec::new());
            rec.states.insert(t, JointState::default());
            rec.base.insert(t, Isometry3::identity());
            rec.cop.insert(t, [0.0, 0.0]);
        }
        rec.support.insert(10, Vec::new());
        rec.support.insert(20, Vec::new());
        assert!(!rec.received_through(30), "support stops at 20");
        assert!(rec.received_through(20));
        rec.support.insert(40, Vec::new());
        assert!(rec.received_through(30));
        assert!(!rec.received_through(31), "phases stop at 30");
    }

    // The walk's start and end, kept as phases come, in order (hand-computed), and against
    // a scan of every phase after each insert of a shuffled stream with ticks said again.
    #[test]
    fn the_walk_span_is_kept_as_phases_come_in_any_order() {
        use super::{PhaseAt, Recording, WalkSpan};
        use gait_planner::PhaseKind;
        let at = |kind| PhaseAt {
            kind,
            step_index: 0,
        };
        let mut rec = Recording::default();
        let kinds = [
            PhaseKind::Idle,
            PhaseKind::Idle,
            PhaseKind::Shift,
            PhaseKind::HalfStep,
            PhaseKind::Idle,
            PhaseKind::Idle,
            PhaseKind::Step,
            PhaseKind::Idle,
        ];
        let mut seen = Vec::new();
        for (t, k) in kinds.iter().enumerate() {
            rec.insert_phase(t as i64 * 10, at(*k));
            seen.push((rec.walk_start_ns(), rec.walk_end_ns()));
        }
        assert_eq!(
            seen,
            [
                (None, None),
                (None, None),
                (Some(20), None),
                (Some(20), None),
                (Some(20), Some(40)),
                (Some(20), Some(40)),
                (Some(20), Some(40)),
                (Some(20), Some(40)),
            ]
        );
        // The end said again as a walking phase moves the end to the next idle tick.
        rec.insert_phase(40, at(PhaseKind::Shift));
        assert_eq!(
            (rec.walk_start_ns(), rec.walk_end_ns()),
            (Some(20), Some(50))
        );
        // The start said again as idle: the walk starts at the next walking tick.
        rec.insert_phase(20, at(PhaseKind::Idle));
        assert_eq!(
            (rec.walk_start_ns(), rec.walk_end_ns()),
            (Some(30), Some(50))
        );

        // The newest tick said again otherwise: the walk's end comes and goes with it.
        let mut rec = Recording::default();
        for (t, k) in [
            (0, PhaseKind::Idle),
            (10, PhaseKind::Step),
            (20, PhaseKind::Idle),
        ] {
            rec.insert_phase(t, at(k));
        }
        assert_eq!(
            (rec.walk_start_ns(), rec.walk_end_ns()),
            (Some(10), Some(20))
        );
        rec.insert_phase(20, at(PhaseKind::Step));
        assert_eq!((rec.walk_start_ns(), rec.walk_end_ns()), (Some(10), None));
        rec.insert_phase(20, at(PhaseKind::Idle));
        assert_eq!(
            (rec.walk_start_ns(), rec.walk_end_ns()),
            (Some(10), Some(20))
        );

        // Any order, ticks said again with another phase: always what a full scan finds.
        let mut rec = Recording::default();
        let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
        for _ in 0..2000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let t = (x % 97) as i64 * 10;
            let kind = if (x >> 20).is_multiple_of(3) {
                PhaseKind::Step
            } else {
                PhaseKind::Idle
            };
            rec.insert_phase(t, at(kind));
            assert_eq!(
                rec.walk,
                WalkSpan::scan(rec.phases()),
                "after {kind:?} at {t}"
            );
        }
    }

    #[test]
    fn the_fall_time_is_read_from_the_report() {
        assert_eq!(
            super::fall_time_ns("the robot fell at t = 4.001 s: base tilted 30.1 deg"),
            Some(4_001_000_000)
        );
        assert_eq!(super::fall_time_ns("fell"), None);
        assert_eq!(super::fall_time_ns("the robot fell at t = NaN s: x"), None);
    }
}
