//! Walk commands waiting for their start time: a bounded queue, taken in arrival order once
//! due, emptied by a stop. Pure: times are passed in (ns of the node's clock, simulated or
//! not), the command type is the caller's.

use std::collections::VecDeque;

/// How many commands may wait at once by default: more than any operator schedules ahead;
/// a sender flooding future commands cannot grow the node without end.
pub const DEFAULT_CAPACITY: usize = 64;

/// A command that could not wait: the queue was full.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "{waiting} walk commands already wait for their start time (at most {capacity}); this one was dropped"
)]
pub struct QueueFull {
    /// Commands waiting.
    pub waiting: usize,
    /// The bound.
    pub capacity: usize,
}

/// Commands with a start time, in arrival order.
#[derive(Debug, Clone)]
pub struct StartQueue<T> {
    items: VecDeque<(i64, T)>,
    capacity: usize,
}

impl<T> Default for StartQueue<T> {
    fn default() -> Self {
        Self::with_capacity(DEFAULT_CAPACITY)
    }
}

impl<T> StartQueue<T> {
    /// An empty queue holding at most `capacity` commands (at least 1).
    pub fn with_capacity(capacity: usize) -> Self {
        Self {
            items: VecDeque::new(),
            capacity: capacity.max(1),
        }
    }

    /// Adds a command to start at `start_ns` (0 or a past time: at the next take).
    pub fn push(&mut self, start_ns: i64, command: T) -> Result<(), QueueFull> {
        if self.items.len() >= self.capacity {
            return Err(QueueFull {
                waiting: self.items.len(),
                capacity: self.capacity,
            });
        }
        self.items.push_back((start_ns, command));
        Ok(())
    }

    /// The first command, in arrival order, whose start time has come at `now_ns`.
    pub fn take_due(&mut self, now_ns: i64) -> Option<T> {
        let i = self.items.iter().position(|(t, _)| *t <= now_ns)?;
        self.items.remove(i).map(|(_, c)| c)
    }

    /// Drops every command still waiting (a stop cancels the walks scheduled after it);
    /// returns how many there were.
    pub fn cancel_all(&mut self) -> usize {
        let n = self.items.len();
        self.items.clear();
        n
    }

    /// Commands waiting.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// True when nothing waits.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn due_commands_come_out_in_arrival_order_and_later_ones_wait() {
        let mut q = StartQueue::default();
        q.push(300, "c").unwrap();
        q.push(100, "a").unwrap();
        q.push(0, "b").unwrap();
        assert_eq!(q.take_due(50), Some("b"));
        assert_eq!(q.take_due(50), None);
        assert_eq!(q.take_due(300), Some("c"), "arrival order among the due");
        assert_eq!(q.take_due(300), Some("a"));
        assert!(q.is_empty());
    }

    #[test]
    fn a_stop_cancels_what_waits_and_a_full_queue_refuses_by_count() {
        let mut q = StartQueue::with_capacity(2);
        q.push(1_000, 1).unwrap();
        q.push(2_000, 2).unwrap();
        let e = q.push(3_000, 3).unwrap_err();
        assert_eq!(
            e,
            QueueFull {
                waiting: 2,
                capacity: 2
            }
        );
        assert!(e.to_string().contains("at most 2"), "{e}");
        assert_eq!(q.cancel_all(), 2);
        assert_eq!(q.take_due(i64::MAX), None);
        q.push(0, 4).unwrap();
        assert_eq!(q.len(), 1);
    }
}
