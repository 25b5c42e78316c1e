//! The application cycle of a reproduced master: a grid of cycle starts one period apart,
//! begun at the first period boundary after the bring-up, and handed out in order up to the
//! true time a scheme's `advance` is asked to reach.

use crate::emu::TrueTime;

/// Cycle starts one period apart.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CycleGrid {
    period: u64,
    next: TrueTime,
}

impl CycleGrid {
    /// A grid of `cycle_ns` (at least 1 ns) whose first start is true time 0 until
    /// [`start_after`](Self::start_after) moves it.
    pub fn new(cycle_ns: u32) -> Self {
        CycleGrid {
            period: u64::from(cycle_ns.max(1)),
            next: 0,
        }
    }

    /// The period, ns.
    pub fn period(&self) -> u64 {
        self.period
    }

    /// The next cycle start.
    pub fn next(&self) -> TrueTime {
        self.next
    }

    /// Starts the grid at the first multiple of the period after `now`.
    pub fn start_after(&mut self, now: TrueTime) {
        self.next = (now / self.period + 1) * self.period;
    }

    /// The next cycle start if it lies before `until`, the grid moving one period on past it.
    pub fn take_before(&mut self, until: TrueTime) -> Option<TrueTime> {
        let t = self.next;
        (t < until).then(|| {
            self.next = t + self.period;
            t
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn starts_on_a_boundary_and_hands_out_cycles_before_until() {
        let mut g = CycleGrid::new(1_000);
        g.start_after(2_500);
        assert_eq!(g.next(), 3_000);
        g.start_after(3_000);
        assert_eq!(g.next(), 4_000, "a boundary at now is not after it");
        let starts: Vec<_> = std::iter::from_fn(|| g.take_before(6_500)).collect();
        assert_eq!(starts, [4_000, 5_000, 6_000]);
        assert_eq!(g.next(), 7_000);
        assert_eq!(g.take_before(7_000), None);
        assert_eq!(CycleGrid::new(0).period(), 1);
    }
}
