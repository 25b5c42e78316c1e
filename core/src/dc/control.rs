//! The machine's control state, for explicit-state model checkers and differential tests
//! (feature `verification`): what decides how the machine reacts to its next input, compared
//! and hashed field by field.
//!
//! Two machines whose control states are equal react identically to every input, up to the
//! diagnostic counters this leaves out. Each field of [`Machine`] is named below, so a new field
//! does not compile until it is either part of the control state or said not to be:
//!
//! - left out, because nothing reads them to decide anything: [`Stats`](crate::dc::Stats) and
//!   the frame count at the last start (read only to report `Stats::lock_frames` and
//!   `Event::Locked::frames`);
//! - left out, because it is a cache rebuilt from the slave table whenever it might not match
//!   it: the round robin's list (`dc/monitor.rs`);
//! - of the working tables (`dc/scratch.rs`) only what one step leaves for the next: the
//!   latest latch round's topology and delays;
//! - the event queue by the events waiting in it, in order, not by where its ring starts.

use core::hash::{Hash, Hasher};

use crate::dc::machine::Machine;

/// A borrowed view of a machine's control state; `Eq` and `Hash` compare only it.
///
/// # Examples
///
/// ```
/// use std::collections::HashSet;
/// use ecdc_core::dc::{Config, Machine};
/// use ecdc_core::time::SystemTime;
///
/// // An explicit-state model checker's visited set: states that react alike are stored once.
/// let idle = Machine::<4>::new(Config::default())?;
/// let mut started = idle.clone();
/// started.start(SystemTime::from_nanos(1_000));
/// let mut seen = HashSet::new();
/// assert!(seen.insert(idle.control_state()));
/// assert!(seen.insert(started.control_state()));
/// assert!(!seen.insert(idle.clone().control_state())); // already explored
/// # Ok::<(), ecdc_core::dc::ConfigError>(())
/// ```
#[derive(Clone, Copy)]
pub struct ControlState<'m, const N: usize> {
    m: &'m Machine<N>,
}

impl<const N: usize> Machine<N> {
    /// The machine's control state (see [`ControlState`]).
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine};
    /// use ecdc_core::time::SystemTime;
    ///
    /// let mut a = Machine::<4>::new(Config::default())?;
    /// let mut b = a.clone();
    /// a.start(SystemTime::from_nanos(1_000));
    /// b.start(SystemTime::from_nanos(1_000));
    /// // Foreign frames only change counters, which are not part of the control state.
    /// b.handle_frame(SystemTime::from_nanos(2_000), &[0u8; 60]);
    /// assert_ne!(a.stats(), b.stats());
    /// assert!(a.control_state() == b.control_state());
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn control_state(&self) -> ControlState<'_, N> {
        ControlState { m: self }
    }

    /// The first broken internal invariant of the timer table (`dc/timer.rs`), if any: the
    /// restart timer is armed exactly in `RestartWait`, the cycle timer exactly in `Cyclic`,
    /// and a reply is awaited only in a request step or in `Cyclic`. For model checkers, which
    /// check it after every input.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::dc::{Config, Machine};
    /// use ecdc_core::time::SystemTime;
    ///
    /// let mut dc = Machine::<4>::new(Config::default())?;
    /// let now = SystemTime::from_nanos(1_000_000_000);
    /// dc.start(now);
    /// let mut frame = [0u8; 1514];
    /// assert!(dc.poll_transmit(now, &mut frame).is_some());
    /// // A model checker asserts this after every input.
    /// assert_eq!(dc.invariant_violation(), None);
    /// # Ok::<(), ecdc_core::dc::ConfigError>(())
    /// ```
    pub fn invariant_violation(&self) -> Option<&'static str> {
        use crate::dc::timer::Timer;
        use crate::dc::State;
        let st = self.state();
        if self.sh.timers.is_set(Timer::Restart) != (st == State::RestartWait) {
            return Some("restart timer armed outside RestartWait, or not in it");
        }
        if self.sh.timers.is_set(Timer::Cycle) != (st == State::Cyclic) {
            return Some("cycle timer armed outside Cyclic, or not in it");
        }
        if self.sh.timers.is_set(Timer::Reply) && !(st == State::Cyclic || st.is_request_step()) {
            return Some("a reply awaited outside a request step and Cyclic");
        }
        None
    }
}

impl<'m, const N: usize> ControlState<'m, N> {
    /// The fields that make up the control state, as one comparable and hashable value.
    fn fields(self) -> impl PartialEq + Hash + 'm {
        let Machine { phase, sh } = self.m;
        let crate::dc::shared::Shared {
            cfg,
            line,
            inflight,
            timers,
            step,
            events,
            stats: _,
            last_sent,
            restarts,
            latch,
            tdiff,
            scratch,
        } = sh;
        (
            (cfg, phase, line, inflight, timers),
            (step, events),
            (last_sent, latch),
            (tdiff, restarts.streak, &scratch.topo, &scratch.round),
        )
    }
}

impl<const N: usize> PartialEq for ControlState<'_, N> {
    fn eq(&self, other: &Self) -> bool {
        self.fields() == other.fields()
    }
}

impl<const N: usize> Eq for ControlState<'_, N> {}

/// The machine's `Debug` form (which shows every field, counters included).
impl<const N: usize> core::fmt::Debug for ControlState<'_, N> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        core::fmt::Debug::fmt(self.m, f)
    }
}

impl<const N: usize> Hash for ControlState<'_, N> {
    fn hash<H: Hasher>(&self, state: &mut H) {
        self.fields().hash(state);
    }
}

#[cfg(test)]
mod tests {
    use core::hash::{Hash, Hasher};
    use std::collections::hash_map::DefaultHasher;

    use crate::dc::{Config, Machine};

    fn hash_of(m: &Machine<4>) -> u64 {
        let mut h = DefaultHasher::new();
        m.control_state().hash(&mut h);
        h.finish()
    }

    #[test]
    fn counters_caches_and_working_tables_are_not_control_state() {
        let a = Machine::<4>::new(Config::default()).unwrap();
        let mut b = a.clone();
        b.sh.stats.frames_sent = 7;
        b.sh.restarts.frames_at_start = 3;
        b.sh.scratch.monitor.invalidate();
        if let Some(s) = b.sh.scratch.subtree.get_mut(0) {
            *s = 5;
        }
        assert_eq!(a.control_state(), b.control_state());
        assert_eq!(hash_of(&a), hash_of(&b));
    }

    #[test]
    fn every_kind_of_control_field_counts() {
        let a = Machine::<4>::new(Config::default()).unwrap();
        let changes: [fn(&mut Machine<4>); 6] = [
            |m| m.sh.step.cursor = 1,
            |m| m.sh.cfg.retries = m.sh.cfg.retries.wrapping_add(1),
            |m| m.sh.line.sync_start = Some(crate::time::SystemTime(1)),
            |m| m.phase = m.phase.enter(crate::dc::State::Failed),
            |m| m.sh.push_event(crate::dc::Event::Restarting),
            |m| m.sh.line.slaves[1].station = 0x1234,
        ];
        for (k, change) in changes.iter().enumerate() {
            let mut b = a.clone();
            change(&mut b);
            assert_ne!(a.control_state(), b.control_state(), "change {k}");
            assert_ne!(hash_of(&a), hash_of(&b), "change {k}");
        }
    }
}
