//! A command's way to the simulated servos when it takes time: what a real robot's servo bus,
//! its driver and the servo's own processing add between a command sent and the servo acting
//! on it. The simulator acts on each command a fixed delay of simulated time after it came, so
//! a gain tuned in simulation can be tried against the latency a robot will have.
//!
//! Pure: simulated time in (ns), items out; nothing here reads a clock.

use std::collections::VecDeque;

/// Items held for a fixed delay of simulated time, handed out in the order they came once
/// due. With no delay an item is due the moment it comes.
#[derive(Debug, Clone)]
pub struct DelayLine<T> {
    delay_ns: i64,
    /// Held items with the time each is due (ns), in the order received. Simulated time does
    /// not go back and the delay is fixed, so the due times never decrease along the queue.
    held: VecDeque<(i64, T)>,
}

impl<T> DelayLine<T> {
    /// At most this many items held: a sender that goes on while simulated time stands still
    /// (a paused simulator) cannot grow the queue without bound.
    pub const MAX_HELD: usize = 1024;

    /// A line that holds each item `delay_ns` of simulated time (a negative delay is none).
    pub fn new(delay_ns: i64) -> Self {
        Self {
            delay_ns: delay_ns.max(0),
            held: VecDeque::new(),
        }
    }

    /// The delay (ns).
    pub fn delay_ns(&self) -> i64 {
        self.delay_ns
    }

    /// `item` received at simulated time `now_ns`, due at `now_ns` + the delay. With
    /// [`Self::MAX_HELD`] items held already, the oldest is handed back to act at once (early,
    /// rather than lost: the items still act in the order they came).
    pub fn push(&mut self, now_ns: i64, item: T) -> Option<T> {
        let out = if self.held.len() >= Self::MAX_HELD {
            self.held.pop_front().map(|(_, it)| it)
        } else {
            None
        };
        self.held
            .push_back((now_ns.saturating_add(self.delay_ns), item));
        out
    }

    /// When the next held item is due (ns), if one is held.
    pub fn next_due_ns(&self) -> Option<i64> {
        self.held.front().map(|(due, _)| *due)
    }

    /// The next held item due at or before `now_ns`, in the order received.
    pub fn pop_due(&mut self, now_ns: i64) -> Option<T> {
        match self.held.front() {
            Some((due, _)) if *due <= now_ns => self.held.pop_front().map(|(_, it)| it),
            _ => None,
        }
    }

    /// How many items are held.
    pub fn len(&self) -> usize {
        self.held.len()
    }

    /// Whether none is held.
    pub fn is_empty(&self) -> bool {
        self.held.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::DelayLine;

    const MS: i64 = 1_000_000;

    fn due<T>(line: &mut DelayLine<T>, now_ns: i64) -> Vec<T> {
        std::iter::from_fn(|| line.pop_due(now_ns)).collect()
    }

    #[test]
    fn without_a_delay_an_item_is_due_as_it_comes() {
        let mut line = DelayLine::new(0);
        assert_eq!(line.push(30 * MS, 'a'), None);
        assert_eq!(line.next_due_ns(), Some(30 * MS));
        assert_eq!(due(&mut line, 30 * MS), vec!['a']);
        assert!(line.is_empty());
        // A negative delay is none.
        assert_eq!(DelayLine::<char>::new(-5 * MS).delay_ns(), 0);
    }

    #[test]
    fn an_item_comes_out_the_delay_after_it_came_in_order() {
        // 15 ms: received at the 10 ms ticks 0, 10 and 20 ms, due at 15, 25 and 35 ms.
        let mut line = DelayLine::new(15 * MS);
        line.push(0, 'a');
        line.push(10 * MS, 'b');
        line.push(10 * MS, 'c');
        line.push(20 * MS, 'd');
        assert!(due(&mut line, 14 * MS).is_empty());
        assert_eq!(line.next_due_ns(), Some(15 * MS));
        assert_eq!(due(&mut line, 15 * MS), vec!['a']);
        assert_eq!(line.next_due_ns(), Some(25 * MS));
        assert!(due(&mut line, 24 * MS).is_empty());
        // Two received at one instant come out together, in the order they came.
        assert_eq!(due(&mut line, 25 * MS), vec!['b', 'c']);
        // Late asking (a stalled simulator) hands out everything due by then.
        line.push(30 * MS, 'e');
        assert_eq!(due(&mut line, 60 * MS), vec!['d', 'e']);
        assert_eq!(line.next_due_ns(), None);
    }

    #[test]
    fn a_full_line_hands_its_oldest_back_rather_than_grow() {
        // Simulated time standing still at 1 s (paused) while a sender goes on.
        let mut line = DelayLine::new(10 * MS);
        for k in 0..DelayLine::<usize>::MAX_HELD {
            assert_eq!(line.push(1000 * MS, k), None);
        }
        assert_eq!(line.push(1000 * MS, 5000), Some(0));
        assert_eq!(line.push(1000 * MS, 5001), Some(1));
        assert_eq!(line.len(), DelayLine::<usize>::MAX_HELD);
        let out = due(&mut line, 1010 * MS);
        assert_eq!(out.len(), DelayLine::<usize>::MAX_HELD);
        assert_eq!((out[0], out[out.len() - 1]), (2, 5001));
    }
}
