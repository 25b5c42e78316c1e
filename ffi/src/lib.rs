//! `ecdc-ffi`: the C ABI of the ecdc Distributed Clocks machine.
//!
//! The header `ffi/include/ecdc.h` is generated from this crate by cbindgen (`ffi/cbindgen.toml`)
//! and documented for C users in `docs/c-api.md`. Layout of the crate:
//! - this module and [`types`]: the `#[repr(C)]` types and every conversion between them and
//!   `ecdc-core`, in safe Rust;
//! - [`abi`]: the `extern "C"` entry points, the only place with `unsafe` (pointer checks and
//!   dereferences, each with a SAFETY comment).
//!
//! Panics: the crate has no panicking code path (the same clippy denials as `ecdc-core`), and
//! every entry point still runs its body under `std::panic::catch_unwind`, so a panic that
//! should not exist becomes `ECDC_ERR_PANIC` instead of unwinding into C. A machine whose call
//! panicked is marked poisoned and refuses further calls. `panic = "abort"` is not an option: it
//! is a profile setting of the final artefact, not of a library crate.
//!
//! Allocation: none after creation. `ecdc_machine_init` places the machine in caller storage
//! (sized by `ecdc_machine_size()`, aligned to `ecdc_machine_align()`) and never allocates;
//! `ecdc_machine_new` does one `Box` allocation. Both produce the same handle.
#![deny(unsafe_code)]
#![deny(missing_docs)]
#![deny(
    clippy::indexing_slicing,
    clippy::arithmetic_side_effects,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::unreachable,
    clippy::cast_possible_truncation
)]

#[allow(unsafe_code)]
pub mod abi;
pub mod types;

pub use abi::*;
pub use types::*;

use ecdc_core::dc::{ConfigError, Event, Machine, State, Stats};
use ecdc_core::time::SystemTime;
use ecdc_core::wire::FrameBuilder;

/// Slave capacity of a machine made by `ecdc_machine_new` / `ecdc_machine_init`.
pub const ECDC_MAX_SLAVES: u32 = 256;
/// Slave capacity of a machine made by `ecdc_machine_new_large` / `ecdc_machine_init_large`.
/// ecdc choice: 1024, the largest network the emulator tests (the 1024-slave line).
pub const ECDC_MAX_SLAVES_LARGE: u32 = 1024;

/// `ECDC_MAX_SLAVES` as a const generic.
pub(crate) const CAP: usize = ECDC_MAX_SLAVES as usize;
/// `ECDC_MAX_SLAVES_LARGE` as a const generic.
pub(crate) const CAP_LARGE: usize = ECDC_MAX_SLAVES_LARGE as usize;

/// Written at the start of a live handle; anything else is refused. It catches use after
/// free and stray pointers in testing, it is no protection against a hostile caller.
pub(crate) const MAGIC_LIVE: u64 = 0x6563_6463_4d41_4348; // "ecdcMACH"
/// Written by `ecdc_machine_free`.
pub(crate) const MAGIC_FREED: u64 = 0x6563_6463_4652_4545; // "ecdcFREE"
/// Written when a call panicked: the machine may be half-updated, so it is never used again.
pub(crate) const MAGIC_POISONED: u64 = 0x6563_6463_504f_4953; // "ecdcPOIS"

/// `Header::owner` of `ecdc_machine_new*`: memory this crate allocated and frees.
pub(crate) const OWNER_LIBRARY: u32 = 1;
/// `Header::owner` of `ecdc_machine_init*`: caller storage, only invalidated by the free.
pub(crate) const OWNER_CALLER: u32 = 2;

/// Prefix of every handle; the layout is fixed by `repr(C)` so it can be read before the
/// capacity is known. Plain integers only: every bit pattern is a valid value, so reading a
/// header from memory that is not a live handle is a refused call, not undefined behaviour
/// of an invalid enum.
#[derive(Debug)]
#[repr(C)]
pub(crate) struct Header {
    pub(crate) magic: u64,
    pub(crate) capacity: u32,
    pub(crate) owner: u32,
}

/// What an `ecdc_machine *` points to.
#[repr(C)]
pub(crate) struct Slot<const N: usize> {
    pub(crate) header: Header,
    pub(crate) machine: Machine<N>,
}

impl<const N: usize> Slot<N> {
    /// A live slot, or the configuration's error.
    pub(crate) fn new(cfg: &ecdc_config, owner: u32) -> Result<Self, ecdc_status> {
        let cfg = config_from_c(cfg)?;
        let machine = Machine::<N>::new(cfg).map_err(status_of_config_error)?;
        Ok(Slot {
            header: Header {
                magic: MAGIC_LIVE,
                capacity: u32::try_from(N).unwrap_or(u32::MAX),
                owner,
            },
            machine,
        })
    }
}

/// The machine operations the ABI exposes, object-safe so one entry point serves every
/// capacity.
pub(crate) trait Api {
    fn start(&mut self, now: u64);
    fn reset(&mut self);
    fn request_delay_measurement(&mut self);
    fn set_slave_t_diff(&mut self, position: u16, t: Option<i32>) -> Result<(), ConfigError>;
    fn state(&self) -> State;
    fn stats(&self) -> Stats;
    fn is_locked(&self) -> bool;
    fn is_awaiting_reply(&self) -> bool;
    fn diff_bound_ns(&self) -> Option<u32>;
    fn reference_time(&self) -> Option<u64>;
    fn slave_count(&self) -> usize;
    fn slave(&self, position: usize) -> Option<ecdc_slave>;
    fn poll_event(&mut self) -> Option<Event>;
    fn poll_timeout(&self) -> Option<u64>;
    fn poll_transmit(&mut self, now: u64, buf: &mut [u8]) -> Option<usize>;
    fn poll_transmit_into(&mut self, now: u64, b: &mut FrameBuilder<'_>) -> bool;
    fn handle_timeout(&mut self, now: u64);
    fn handle_frame(&mut self, now: u64, bytes: &[u8]);
}

impl<const N: usize> Api for Machine<N> {
    fn start(&mut self, now: u64) {
        Machine::start(self, SystemTime(now));
    }
    fn reset(&mut self) {
        Machine::reset(self);
    }
    fn request_delay_measurement(&mut self) {
        Machine::request_delay_measurement(self);
    }
    fn set_slave_t_diff(&mut self, position: u16, t: Option<i32>) -> Result<(), ConfigError> {
        Machine::set_slave_t_diff(self, position, t).map(|_| ())
    }
    fn state(&self) -> State {
        Machine::state(self)
    }
    fn stats(&self) -> Stats {
        *Machine::stats(self)
    }
    fn is_locked(&self) -> bool {
        Machine::is_locked(self)
    }
    fn is_awaiting_reply(&self) -> bool {
        Machine::is_awaiting_reply(self)
    }
    fn diff_bound_ns(&self) -> Option<u32> {
        Machine::diff_bound_ns(self)
    }
    fn reference_time(&self) -> Option<u64> {
        Machine::reference_time(self).map(SystemTime::as_nanos)
    }
    fn slave_count(&self) -> usize {
        self.slaves().len()
    }
    fn slave(&self, position: usize) -> Option<ecdc_slave> {
        let reference = Machine::reference(self);
        self.slaves()
            .get(position)
            .map(|s| slave_to_c(s, u16::try_from(position).ok() == reference))
    }
    fn poll_event(&mut self) -> Option<Event> {
        Machine::poll_event(self)
    }
    fn poll_timeout(&self) -> Option<u64> {
        Machine::poll_timeout(self).map(SystemTime::as_nanos)
    }
    fn poll_transmit(&mut self, now: u64, buf: &mut [u8]) -> Option<usize> {
        Machine::poll_transmit(self, SystemTime(now), buf)
    }
    fn poll_transmit_into(&mut self, now: u64, b: &mut FrameBuilder<'_>) -> bool {
        Machine::poll_transmit_into(self, SystemTime(now), b)
    }
    fn handle_timeout(&mut self, now: u64) {
        Machine::handle_timeout(self, SystemTime(now));
    }
    fn handle_frame(&mut self, now: u64, bytes: &[u8]) {
        Machine::handle_frame(self, SystemTime(now), bytes);
    }
}
