//! [`SignRun`]: how many judgements in a row went the same way. The outlier gate confirms a
//! persistent offset after `confirm` same-sign rejections, and the servo steps after
//! `step_confirm` same-sign large errors; both count with this.

/// The length of the current run of same-sign events (0: none yet) and its sign.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) struct SignRun {
    len: u8,
    positive: bool,
}

impl SignRun {
    /// No run.
    pub(crate) const fn new() -> Self {
        SignRun {
            len: 0,
            positive: false,
        }
    }

    /// Counts an event of sign `positive`: the run grows (saturating at 255) if it has the
    /// run's sign, else a new run of 1 starts. Returns the run's length.
    #[inline(always)]
    pub(crate) fn push(&mut self, positive: bool) -> u8 {
        if self.len == 0 || positive != self.positive {
            self.len = 1;
            self.positive = positive;
        } else {
            self.len = self.len.saturating_add(1);
        }
        self.len
    }

    /// Ends the run.
    #[inline(always)]
    pub(crate) fn clear(&mut self) {
        self.len = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Same signs extend the run, a change of sign or a clear restarts it, the length
    /// saturates.
    #[test]
    fn runs() {
        let mut r = SignRun::new();
        assert_eq!([r.push(true), r.push(true), r.push(true)], [1, 2, 3]);
        assert_eq!([r.push(false), r.push(false)], [1, 2]);
        assert_eq!(r.push(true), 1);
        r.clear();
        assert_eq!(r.push(true), 1);
        r.clear();
        assert_eq!(
            r.push(false),
            1,
            "a cleared run restarts even with the same sign"
        );
        for _ in 0..300 {
            r.push(false);
        }
        assert_eq!(r.push(false), u8::MAX);
        assert_eq!(
            SignRun::new(),
            SignRun {
                len: 0,
                positive: false
            }
        );
    }
}
