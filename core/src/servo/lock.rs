//! Lock detector with hysteresis (REQ-SERVO-060).
//!
//! `locked` rises only after `count` consecutive samples with |θ| < `low`, and falls only on a
//! sample with |θ| > `high` (or an explicit [`LockDetector::unlock`], e.g. after a step or a
//! holdover timeout). Between the thresholds it keeps its state, so jitter around one threshold
//! cannot make the flag chatter.

/// Lock thresholds.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::lock::{LockConfig, LockDetector};
///
/// // Lock after 3 samples within 100 ns; drop only beyond 500 ns.
/// let cfg = LockConfig {
///     low_ns: 100,
///     high_ns: 500,
///     count: 3,
/// }
/// .validate()?;
/// let mut lock = LockDetector::new();
/// let states = [50, -60, 70, 300, -600].map(|theta| lock.update(&cfg, theta));
/// assert_eq!(states, [false, false, true, true, false]);
/// # Ok::<(), ecdc_core::servo::lock::LockError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LockConfig {
    /// |θ| below this counts toward lock, ns.
    pub low_ns: u64,
    /// |θ| above this drops lock, ns (≥ low).
    pub high_ns: u64,
    /// Consecutive samples below `low` needed to lock (N_L ≥ 1).
    pub count: u16,
}

/// Why a lock configuration was refused.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::lock::{LockConfig, LockError};
///
/// let bad = LockConfig {
///     low_ns: 500,
///     high_ns: 100,
///     count: 3,
/// };
/// assert_eq!(bad.validate(), Err(LockError::Thresholds));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LockError {
    /// Need low ≤ high and count ≥ 1.
    Thresholds,
}

impl LockConfig {
    /// Validate low ≤ high, count ≥ 1.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::lock::{LockConfig, LockError};
    ///
    /// let cfg = LockConfig {
    ///     low_ns: 100,
    ///     high_ns: 500,
    ///     count: 3,
    /// };
    /// assert_eq!(cfg.validate(), Ok(cfg));
    /// assert_eq!(
    ///     LockConfig { count: 0, ..cfg }.validate(),
    ///     Err(LockError::Thresholds)
    /// );
    /// ```
    pub fn validate(self) -> Result<Self, LockError> {
        if self.low_ns > self.high_ns || self.count == 0 {
            return Err(LockError::Thresholds);
        }
        Ok(self)
    }
}

/// Lock state.
///
/// # Examples
///
/// ```
/// use ecdc_core::servo::lock::{LockConfig, LockDetector};
///
/// let cfg = LockConfig {
///     low_ns: 100,
///     high_ns: 500,
///     count: 1,
/// };
/// let mut lock = LockDetector::new();
/// assert!(lock.update(&cfg, 20));
/// assert!(lock.is_locked());
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct LockDetector {
    below: u16,
    locked: bool,
}

impl LockDetector {
    /// Unlocked, no history.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::lock::LockDetector;
    ///
    /// assert!(!LockDetector::new().is_locked());
    /// ```
    pub const fn new() -> Self {
        LockDetector {
            below: 0,
            locked: false,
        }
    }

    /// Current state.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::lock::{LockConfig, LockDetector};
    ///
    /// let cfg = LockConfig {
    ///     low_ns: 100,
    ///     high_ns: 500,
    ///     count: 2,
    /// };
    /// let mut lock = LockDetector::new();
    /// lock.update(&cfg, 20);
    /// assert!(!lock.is_locked()); // one of two samples
    /// lock.update(&cfg, 30);
    /// assert!(lock.is_locked());
    /// ```
    pub const fn is_locked(&self) -> bool {
        self.locked
    }

    /// Feed one accepted error; returns the new state.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::lock::{LockConfig, LockDetector};
    ///
    /// let cfg = LockConfig {
    ///     low_ns: 100,
    ///     high_ns: 500,
    ///     count: 2,
    /// };
    /// let mut lock = LockDetector::new();
    /// // A sample between the thresholds breaks the run towards lock.
    /// let states = [20, 200, 20, 20].map(|theta| lock.update(&cfg, theta));
    /// assert_eq!(states, [false, false, false, true]);
    /// ```
    pub fn update(&mut self, cfg: &LockConfig, theta: i64) -> bool {
        let a = theta.unsigned_abs();
        if self.locked {
            if a > cfg.high_ns {
                self.locked = false;
                self.below = 0;
            }
        } else if a < cfg.low_ns {
            self.below = self.below.saturating_add(1);
            if self.below >= cfg.count {
                self.locked = true;
            }
        } else {
            self.below = 0;
        }
        self.locked
    }

    /// Drop lock and history.
    ///
    /// # Examples
    ///
    /// ```
    /// use ecdc_core::servo::lock::{LockConfig, LockDetector};
    ///
    /// let cfg = LockConfig {
    ///     low_ns: 100,
    ///     high_ns: 500,
    ///     count: 1,
    /// };
    /// let mut lock = LockDetector::new();
    /// lock.update(&cfg, 0);
    /// lock.unlock(); // the clock was stepped
    /// assert!(!lock.is_locked());
    /// ```
    pub fn unlock(&mut self) {
        *self = Self::new();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hysteresis() {
        let cfg = LockConfig {
            low_ns: 100,
            high_ns: 300,
            count: 3,
        }
        .validate()
        .unwrap();
        let mut d = LockDetector::new();
        assert!(!d.update(&cfg, 50));
        assert!(!d.update(&cfg, 50));
        assert!(!d.update(&cfg, 150)); // resets the run
        assert!(!d.update(&cfg, -50));
        assert!(!d.update(&cfg, 50));
        assert!(d.update(&cfg, 99));
        assert!(d.update(&cfg, 300)); // between thresholds: stays locked
        assert!(!d.update(&cfg, -301));
        assert!(LockConfig {
            low_ns: 2,
            high_ns: 1,
            count: 1
        }
        .validate()
        .is_err());
    }
}
