//! How a request step's items map to slaves. A step's items are numbered `0..item_count`
//! (`dc/steps.rs`); a step that sends several datagrams to each slave numbers them slave by
//! slave, and [`PerSlave`] turns an item number back into the slave's position and the typed
//! datagram, so no step computes strides by hand.

/// The datagrams a step sends to each slave, in sending order: item `i` is datagram
/// `ALL[i % ALL.len()]` of the slave at position `i / ALL.len()`.
pub(crate) trait PerSlave: Copy + 'static {
    /// Every datagram of one slave, in sending order.
    const ALL: &'static [Self];

    /// Item `i` as (position, datagram).
    fn of(i: u16) -> Option<(u16, Self)> {
        let per = u16::try_from(Self::ALL.len()).ok()?;
        let pos = i.checked_div(per)?;
        let k = i.checked_rem(per)?;
        Some((pos, *Self::ALL.get(usize::from(k))?))
    }

    /// The step's item count for `count` slaves.
    fn items(count: u16) -> u16 {
        let per = u16::try_from(Self::ALL.len()).unwrap_or(u16::MAX);
        count.saturating_mul(per)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Clone, Copy, PartialEq)]
    enum Three {
        A,
        B,
        C,
    }

    impl PerSlave for Three {
        const ALL: &'static [Self] = &[Three::A, Three::B, Three::C];
    }

    #[test]
    fn items_number_slave_by_slave() {
        assert_eq!(Three::items(4), 12);
        assert_eq!(Three::items(u16::MAX), u16::MAX);
        let items: std::vec::Vec<_> = (0..Three::items(2)).map(Three::of).collect();
        assert_eq!(
            items,
            [
                Some((0, Three::A)),
                Some((0, Three::B)),
                Some((0, Three::C)),
                Some((1, Three::A)),
                Some((1, Three::B)),
                Some((1, Three::C)),
            ]
        );
        assert_eq!(Three::of(u16::MAX), Some((21845, Three::A)));
    }
}
