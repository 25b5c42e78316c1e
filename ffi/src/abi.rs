//! The `extern "C"` entry points: the only module with `unsafe`.
//!
//! Every function checks its pointers for NULL (and handles for alignment and the live magic)
//! before dereferencing, and runs the work under `catch_unwind` (see the crate docs). What it
//! cannot check is stated in its `# Safety` section and in `docs/c-api.md`: pointers must point
//! to memory of the stated size, valid for the call, not aliased by another thread.
#![allow(non_camel_case_types)]

use core::ffi::{c_char, c_int, c_void};
use core::ptr;
use std::alloc::{self, Layout};
use std::panic::{catch_unwind, AssertUnwindSafe};

use ecdc_core::dc::Config;
use ecdc_core::wire::{self, Address, Command, FrameBuilder, MIN_FRAME_LEN};

use crate::types::*;
use crate::{
    state_name, state_to_c, Api, Header, Slot, CAP, CAP_LARGE, MAGIC_FREED, MAGIC_LIVE,
    MAGIC_POISONED, OWNER_CALLER, OWNER_LIBRARY,
};

/// Opaque machine handle. Made by `ecdc_machine_new*` or `ecdc_machine_init*`, released by
/// `ecdc_machine_free`. One thread at a time.
pub struct ecdc_machine {
    _opaque: [u8; 0],
}

use ecdc_status as S;

// ----- handle access ------------------------------------------------------------------------

/// Reads the header of a handle candidate and returns its capacity if it is live.
///
/// # Safety
/// `m` is NULL or points to at least `size_of::<Header>()` readable bytes.
unsafe fn live_capacity(m: *const ecdc_machine) -> Result<u32, ecdc_status> {
    if m.is_null() {
        return Err(S::ECDC_ERR_NULL);
    }
    let h = m.cast::<Header>();
    if !h.is_aligned() {
        return Err(S::ECDC_ERR_INVALID_HANDLE);
    }
    // SAFETY: non-null and aligned (checked above), readable by the caller's contract; the
    // fields are plain integers, so any bit pattern is a valid value. Read by raw place, no
    // reference to a possibly foreign object is created.
    let (magic, capacity) = unsafe {
        (
            ptr::addr_of!((*h).magic).read(),
            ptr::addr_of!((*h).capacity).read(),
        )
    };
    match magic {
        MAGIC_LIVE => Ok(capacity),
        MAGIC_POISONED => Err(S::ECDC_ERR_POISONED),
        _ => Err(S::ECDC_ERR_INVALID_HANDLE),
    }
}

/// The machine behind a live handle, mutable.
///
/// # Safety
/// As [`live_capacity`]; a live handle's memory holds the `Slot` its header names, and the
/// caller does not use it from another thread during the call.
unsafe fn api_mut<'a>(m: *mut ecdc_machine) -> Result<&'a mut dyn Api, ecdc_status> {
    // SAFETY: forwarded contract.
    let cap = unsafe { live_capacity(m) }?;
    match cap {
        // SAFETY: a live header with this capacity was written by `install::<N>` at the start
        // of a `Slot<N>` (same address, `repr(C)`), which stays valid until `ecdc_machine_free`
        // overwrites the magic; exclusive access by the caller's contract.
        crate::ECDC_MAX_SLAVES => Ok(unsafe { &mut (*m.cast::<Slot<CAP>>()).machine }),
        // SAFETY: as above for the large capacity.
        crate::ECDC_MAX_SLAVES_LARGE => Ok(unsafe { &mut (*m.cast::<Slot<CAP_LARGE>>()).machine }),
        _ => Err(S::ECDC_ERR_INVALID_HANDLE),
    }
}

/// The machine behind a live handle, shared.
///
/// # Safety
/// As [`api_mut`], with no concurrent mutation.
unsafe fn api_ref<'a>(m: *const ecdc_machine) -> Result<&'a dyn Api, ecdc_status> {
    // SAFETY: forwarded contract.
    let cap = unsafe { live_capacity(m) }?;
    match cap {
        // SAFETY: see `api_mut`.
        crate::ECDC_MAX_SLAVES => Ok(unsafe { &(*m.cast::<Slot<CAP>>()).machine }),
        // SAFETY: see `api_mut`.
        crate::ECDC_MAX_SLAVES_LARGE => Ok(unsafe { &(*m.cast::<Slot<CAP_LARGE>>()).machine }),
        _ => Err(S::ECDC_ERR_INVALID_HANDLE),
    }
}

/// Marks a handle poisoned after a panic inside a call.
///
/// # Safety
/// `m` is a handle `live_capacity` accepted in this call, no reference into it is alive.
unsafe fn poison(m: *mut ecdc_machine) {
    // SAFETY: non-null, aligned, writable header by the caller's contract.
    unsafe { ptr::addr_of_mut!((*m.cast::<Header>()).magic).write(MAGIC_POISONED) };
}

/// Runs `f` on the machine behind `m` under `catch_unwind`; `fail` turns a refused handle or a
/// panic into the function's return value.
///
/// # Safety
/// As [`api_mut`].
unsafe fn with_mut<R>(
    m: *mut ecdc_machine,
    fail: impl FnOnce(ecdc_status) -> R,
    f: impl FnOnce(&mut dyn Api) -> R,
) -> R {
    // SAFETY: forwarded contract.
    let api = match unsafe { api_mut(m) } {
        Ok(a) => a,
        Err(e) => return fail(e),
    };
    match catch_unwind(AssertUnwindSafe(|| f(api))) {
        Ok(r) => r,
        Err(_) => {
            // SAFETY: the closure and its borrow of the machine are gone.
            unsafe { poison(m) };
            fail(S::ECDC_ERR_PANIC)
        }
    }
}

/// [`with_mut`] for read-only calls (a panic there cannot leave the machine half-updated, so
/// it does not poison).
///
/// # Safety
/// As [`api_ref`].
unsafe fn with_ref<R>(
    m: *const ecdc_machine,
    fail: impl FnOnce(ecdc_status) -> R,
    f: impl FnOnce(&dyn Api) -> R,
) -> R {
    // SAFETY: forwarded contract.
    let api = match unsafe { api_ref(m) } {
        Ok(a) => a,
        Err(e) => return fail(e),
    };
    catch_unwind(AssertUnwindSafe(|| f(api))).unwrap_or_else(|_| fail(S::ECDC_ERR_PANIC))
}

/// `catch_unwind` for calls without a machine.
fn guard<R>(fail: R, f: impl FnOnce() -> R) -> R {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or(fail)
}

fn status(r: Result<(), ecdc_status>) -> ecdc_status {
    r.err().unwrap_or(S::ECDC_OK)
}

/// `ECDC_OK` with `r`'s value written to `*out` (not written when `out` is NULL), or `r`'s
/// error.
///
/// # Safety
/// `out` is NULL or valid for writes of a `T`.
unsafe fn write_out<T>(r: Result<T, ecdc_status>, out: *mut T) -> ecdc_status {
    match r {
        Ok(v) => {
            if !out.is_null() {
                // SAFETY: non-null, writable (contract).
                unsafe { out.write(v) };
            }
            S::ECDC_OK
        }
        Err(e) => e,
    }
}

// ----- library information ------------------------------------------------------------------

/// Library version ("0.1.0"), a static NUL-terminated string.
#[no_mangle]
pub extern "C" fn ecdc_version() -> *const c_char {
    concat!(env!("CARGO_PKG_VERSION"), "\0").as_ptr().cast()
}

/// Static NUL-terminated description of a status code (any value).
#[no_mangle]
pub extern "C" fn ecdc_strerror(status: c_int) -> *const c_char {
    guard(c"unknown ecdc status code".as_ptr(), || {
        strerror(i64::from(status)).as_ptr()
    })
}

/// Static NUL-terminated lower-case name of an `ecdc_machine_state` value ("unknown" for others).
#[no_mangle]
pub extern "C" fn ecdc_state_name(state: c_int) -> *const c_char {
    guard(c"unknown".as_ptr(), || {
        state_name(i64::from(state)).as_ptr()
    })
}

/// Fills `*out` with the default configuration (the defaults of `ecdc_core::dc::Config`).
///
/// # Safety
/// `out` is NULL or points to a writable `ecdc_config`.
#[no_mangle]
pub unsafe extern "C" fn ecdc_config_default(out: *mut ecdc_config) -> ecdc_status {
    if out.is_null() {
        return S::ECDC_ERR_NULL;
    }
    let c = guard(None, || Some(config_to_c(&Config::default())));
    let Some(c) = c else {
        return S::ECDC_ERR_PANIC;
    };
    // SAFETY: non-null, writable by the caller's contract; `write` does not read the old value.
    unsafe { out.write(c) };
    S::ECDC_OK
}

// ----- creation and release ------------------------------------------------------------------

/// Bytes of caller storage `ecdc_machine_init` needs (capacity `ECDC_MAX_SLAVES`).
#[no_mangle]
pub extern "C" fn ecdc_machine_size() -> usize {
    core::mem::size_of::<Slot<CAP>>()
}

/// Bytes of caller storage `ecdc_machine_init_large` needs (capacity `ECDC_MAX_SLAVES_LARGE`).
#[no_mangle]
pub extern "C" fn ecdc_machine_size_large() -> usize {
    core::mem::size_of::<Slot<CAP_LARGE>>()
}

/// Alignment the storage of `ecdc_machine_init*` must have (both capacities).
#[no_mangle]
pub extern "C" fn ecdc_machine_align() -> usize {
    core::mem::align_of::<Slot<CAP>>().max(core::mem::align_of::<Slot<CAP_LARGE>>())
}

/// Builds a `Slot<N>` at `at`.
///
/// # Safety
/// `at` is valid for writes of a `Slot<N>` and aligned for it.
unsafe fn install<const N: usize>(
    at: *mut c_void,
    cfg: &ecdc_config,
    owner: u32,
) -> Result<*mut ecdc_machine, ecdc_status> {
    let slot = guard(Err(S::ECDC_ERR_PANIC), || Slot::<N>::new(cfg, owner))?;
    // SAFETY: valid and aligned by the caller's contract; `write` does not drop old contents.
    unsafe { at.cast::<Slot<N>>().write(slot) };
    Ok(at.cast())
}

/// # Safety
/// See [`ecdc_machine_init`].
unsafe fn init<const N: usize>(
    storage: *mut c_void,
    size: usize,
    cfg: *const ecdc_config,
    out: *mut *mut ecdc_machine,
) -> ecdc_status {
    if storage.is_null() || cfg.is_null() || out.is_null() {
        return S::ECDC_ERR_NULL;
    }
    if size < core::mem::size_of::<Slot<N>>() {
        return S::ECDC_ERR_STORAGE_TOO_SMALL;
    }
    if !storage.cast::<Slot<N>>().is_aligned() {
        return S::ECDC_ERR_STORAGE_MISALIGNED;
    }
    // SAFETY: non-null, a readable `ecdc_config` by the caller's contract; every field is a
    // plain integer, so any bit pattern is valid.
    let cfg = unsafe { cfg.read() };
    // SAFETY: `size` bytes at `storage` are writable (contract), enough and aligned (checked).
    match unsafe { install::<N>(storage, &cfg, OWNER_CALLER) } {
        Ok(m) => {
            // SAFETY: non-null, writable by contract.
            unsafe { out.write(m) };
            S::ECDC_OK
        }
        Err(e) => e,
    }
}

/// Places a machine (capacity `ECDC_MAX_SLAVES`) in caller storage; never allocates. On success
/// `*out` is the handle (equal to `storage`); on failure `*out` is untouched.
///
/// # Safety
/// `storage` is NULL or valid for writes of `size` bytes and not used otherwise until
/// `ecdc_machine_free`; `cfg` is NULL or points to an `ecdc_config`; `out` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ecdc_machine_init(
    storage: *mut c_void,
    size: usize,
    cfg: *const ecdc_config,
    out: *mut *mut ecdc_machine,
) -> ecdc_status {
    // SAFETY: forwarded contract.
    unsafe { init::<CAP>(storage, size, cfg, out) }
}

/// [`ecdc_machine_init`] for capacity `ECDC_MAX_SLAVES_LARGE` (`ecdc_machine_size_large()`).
///
/// # Safety
/// As [`ecdc_machine_init`].
#[no_mangle]
pub unsafe extern "C" fn ecdc_machine_init_large(
    storage: *mut c_void,
    size: usize,
    cfg: *const ecdc_config,
    out: *mut *mut ecdc_machine,
) -> ecdc_status {
    // SAFETY: forwarded contract.
    unsafe { init::<CAP_LARGE>(storage, size, cfg, out) }
}

/// # Safety
/// See [`ecdc_machine_new`].
unsafe fn new<const N: usize>(cfg: *const ecdc_config, out: *mut *mut ecdc_machine) -> ecdc_status {
    if cfg.is_null() || out.is_null() {
        return S::ECDC_ERR_NULL;
    }
    // SAFETY: non-null, readable (contract), plain integer fields.
    let cfg = unsafe { cfg.read() };
    // Validate before allocating, so a bad config costs no allocation. Only the config is
    // checked here: building a whole machine just to throw it away would put one more
    // machine-sized value on the caller's stack (230 KiB for the large capacity).
    if let Err(e) = guard(Err(S::ECDC_ERR_PANIC), || {
        let rust = config_from_c(&cfg)?;
        rust.validate(N).map_err(status_of_config_error)
    }) {
        return e;
    }
    let layout = Layout::new::<Slot<N>>();
    // SAFETY: the layout has a non-zero size (a Slot holds at least its header).
    let mem = unsafe { alloc::alloc(layout) };
    if mem.is_null() {
        return S::ECDC_ERR_ALLOC;
    }
    // SAFETY: freshly allocated with the Slot<N> layout: valid for writes and aligned.
    match unsafe { install::<N>(mem.cast(), &cfg, OWNER_LIBRARY) } {
        Ok(m) => {
            // SAFETY: non-null, writable by contract.
            unsafe { out.write(m) };
            S::ECDC_OK
        }
        Err(e) => {
            // SAFETY: allocated above with this layout, nothing was installed.
            unsafe { alloc::dealloc(mem, layout) };
            e
        }
    }
}

/// Allocates a machine (capacity `ECDC_MAX_SLAVES`) with one allocation; the only allocation
/// the library ever makes. On failure `*out` is untouched.
///
/// # Safety
/// `cfg` is NULL or points to an `ecdc_config`; `out` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ecdc_machine_new(
    cfg: *const ecdc_config,
    out: *mut *mut ecdc_machine,
) -> ecdc_status {
    // SAFETY: forwarded contract.
    unsafe { new::<CAP>(cfg, out) }
}

/// [`ecdc_machine_new`] for capacity `ECDC_MAX_SLAVES_LARGE`.
///
/// # Safety
/// As [`ecdc_machine_new`].
#[no_mangle]
pub unsafe extern "C" fn ecdc_machine_new_large(
    cfg: *const ecdc_config,
    out: *mut *mut ecdc_machine,
) -> ecdc_status {
    // SAFETY: forwarded contract.
    unsafe { new::<CAP_LARGE>(cfg, out) }
}

/// # Safety
/// `m` is a live or poisoned handle of capacity `N`.
unsafe fn release<const N: usize>(m: *mut ecdc_machine) {
    let slot = m.cast::<Slot<N>>();
    // SAFETY: a live/poisoned header (checked by the caller) heads a `Slot<N>`.
    let owner = unsafe { ptr::addr_of!((*slot).header.owner).read() };
    // SAFETY: the machine was written by `install` and is dropped exactly once: the magic is
    // overwritten next, so a second free is refused.
    unsafe { ptr::drop_in_place(ptr::addr_of_mut!((*slot).machine)) };
    // SAFETY: header writable.
    unsafe { ptr::addr_of_mut!((*slot).header.magic).write(MAGIC_FREED) };
    if owner == OWNER_LIBRARY {
        // SAFETY: allocated by `new::<N>` with exactly this layout.
        unsafe { alloc::dealloc(m.cast(), Layout::new::<Slot<N>>()) };
    }
}

/// Releases a handle: frees what `ecdc_machine_new*` allocated, or invalidates caller storage
/// of `ecdc_machine_init*` (which the caller may then reuse). NULL, a freed or a foreign
/// pointer is ignored (as far as the header check can tell). A poisoned machine is released.
///
/// # Safety
/// `m` is NULL or a pointer from `ecdc_machine_new*`/`ecdc_machine_init*`, not used again.
#[no_mangle]
pub unsafe extern "C" fn ecdc_machine_free(m: *mut ecdc_machine) {
    // SAFETY: contract: NULL or a handle's memory.
    let cap = match unsafe { live_capacity(m) } {
        Ok(c) => c,
        Err(S::ECDC_ERR_POISONED) => {
            // SAFETY: header readable (accepted by live_capacity).
            unsafe { ptr::addr_of!((*m.cast::<Header>()).capacity).read() }
        }
        Err(_) => return,
    };
    // Dropping a `Machine` runs no code (plain data); the guard is for the principle.
    guard((), || match cap {
        // SAFETY: live or poisoned handle of this capacity.
        crate::ECDC_MAX_SLAVES => unsafe { release::<CAP>(m) },
        // SAFETY: as above.
        crate::ECDC_MAX_SLAVES_LARGE => unsafe { release::<CAP_LARGE>(m) },
        _ => {}
    });
}

/// Slave capacity of a handle, 0 if it is not live.
///
/// # Safety
/// `m` is NULL or a handle pointer.
#[no_mangle]
pub unsafe extern "C" fn ecdc_machine_capacity(m: *const ecdc_machine) -> u32 {
    // SAFETY: forwarded contract.
    unsafe { live_capacity(m) }.unwrap_or(0)
}

// ----- commands ------------------------------------------------------------------------------

/// Starts (or restarts) the bring-up at `now_ns` (ns since 2000-01-01, the master's clock).
///
/// # Safety
/// `m` is NULL or a handle, used by no other thread during the call (all `ecdc_*` functions
/// taking a machine have this contract).
#[no_mangle]
pub unsafe extern "C" fn ecdc_start(m: *mut ecdc_machine, now_ns: u64) -> ecdc_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_mut(
            m,
            |e| e,
            |a| {
                a.start(now_ns);
                S::ECDC_OK
            },
        )
    }
}

/// Stops everything and returns to `ECDC_STATE_IDLE`.
///
/// # Safety
/// As [`ecdc_start`].
#[no_mangle]
pub unsafe extern "C" fn ecdc_reset(m: *mut ecdc_machine) -> ecdc_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_mut(
            m,
            |e| e,
            |a| {
                a.reset();
                S::ECDC_OK
            },
        )
    }
}

/// Asks for a propagation-delay re-measurement in cyclic operation (ignored otherwise).
///
/// # Safety
/// As [`ecdc_start`].
#[no_mangle]
pub unsafe extern "C" fn ecdc_request_delay_measurement(m: *mut ecdc_machine) -> ecdc_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_mut(
            m,
            |e| e,
            |a| {
                a.request_delay_measurement();
                S::ECDC_OK
            },
        )
    }
}

/// Sets `t_Diff` (ns) of the slave at auto-increment `position`, used from the next delay
/// measurement; `ECDC_ERR_CAPACITY` beyond the capacity.
///
/// # Safety
/// As [`ecdc_start`].
#[no_mangle]
pub unsafe extern "C" fn ecdc_set_slave_t_diff(
    m: *mut ecdc_machine,
    position: u16,
    t_diff_ns: i32,
) -> ecdc_status {
    // SAFETY: forwarded contract.
    unsafe { set_t_diff(m, position, Some(t_diff_ns)) }
}

/// Removes the `t_Diff` override of a slave (it uses `ecdc_config.t_diff_ns` again).
///
/// # Safety
/// As [`ecdc_start`].
#[no_mangle]
pub unsafe extern "C" fn ecdc_clear_slave_t_diff(
    m: *mut ecdc_machine,
    position: u16,
) -> ecdc_status {
    // SAFETY: forwarded contract.
    unsafe { set_t_diff(m, position, None) }
}

/// Sets (`Some`) or removes (`None`) the `t_Diff` override of the slave at `position`.
///
/// # Safety
/// As [`ecdc_start`].
unsafe fn set_t_diff(m: *mut ecdc_machine, position: u16, t_diff_ns: Option<i32>) -> ecdc_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_mut(
            m,
            |e| e,
            |a| {
                status(
                    a.set_slave_t_diff(position, t_diff_ns)
                        .map_err(status_of_config_error),
                )
            },
        )
    }
}

// ----- output --------------------------------------------------------------------------------

/// Writes the machine's next frame (a complete Ethernet frame, padded to 60 bytes) into
/// `buf[0..capacity)` and returns its length; 0 when nothing is to be sent now, or for a NULL
/// or invalid argument. Call until it returns 0. A buffer below 60 bytes produces an
/// `ECDC_FAULT_BUFFER_TOO_SMALL` event; 1514 bytes always suffice.
///
/// # Safety
/// As [`ecdc_start`]; `buf` is NULL or valid for writes of `capacity` bytes.
#[no_mangle]
pub unsafe extern "C" fn ecdc_poll_transmit(
    m: *mut ecdc_machine,
    now_ns: u64,
    buf: *mut u8,
    capacity: usize,
) -> usize {
    if buf.is_null() {
        return 0;
    }
    // SAFETY: non-null and valid for `capacity` writes (contract); not aliased by the machine,
    // which lives in its own storage.
    let out = unsafe { core::slice::from_raw_parts_mut(buf, capacity) };
    // SAFETY: forwarded contract.
    unsafe { with_mut(m, |_| 0, |a| a.poll_transmit(now_ns, out).unwrap_or(0)) }
}

/// The frame behind an `ecdc_frame` and its buffer.
///
/// # Safety
/// `f` is NULL or a writable `ecdc_frame` whose `buf` is NULL or valid for writes of
/// `capacity` bytes and does not overlap `*f`.
unsafe fn frame_parts<'a>(
    f: *mut ecdc_frame,
) -> Result<(&'a mut ecdc_frame, &'a mut [u8]), ecdc_status> {
    if f.is_null() {
        return Err(S::ECDC_ERR_NULL);
    }
    // SAFETY: non-null, writable `ecdc_frame` (contract); every field is valid for any bits.
    let fr = unsafe { &mut *f };
    if fr.buf.is_null() {
        return Err(S::ECDC_ERR_NULL);
    }
    if fr.capacity < MIN_FRAME_LEN {
        return Err(S::ECDC_ERR_BUFFER_TOO_SMALL);
    }
    // SAFETY: `buf` valid for `capacity` writes and disjoint from `*f` (contract).
    let buf = unsafe { core::slice::from_raw_parts_mut(fr.buf, fr.capacity) };
    Ok((fr, buf))
}

fn frame_error(e: wire::Error) -> ecdc_status {
    match e {
        wire::Error::BufferFull => S::ECDC_ERR_FRAME_FULL,
        wire::Error::NoDatagram => S::ECDC_ERR_FRAME_EMPTY,
        wire::Error::DatagramTooLong { .. }
        | wire::Error::AddressMismatch
        | wire::Error::UnknownCommand { .. } => S::ECDC_ERR_ARGUMENT,
        _ => S::ECDC_ERR_FRAME_INVALID,
    }
}

/// Whether `buf` holds a frame as `ecdc_frame_init` leaves it: untagged EtherType 0x88A4 and
/// an EtherCAT header with length 0, which `FrameBuilder::resume` (a parser of complete
/// frames) does not accept.
fn is_fresh_frame(buf: &[u8]) -> bool {
    let ethertype = buf.get(12..14) == Some(&[0x88, 0xA4][..]);
    let header = buf
        .get(14..16)
        .and_then(|h| <[u8; 2]>::try_from(h).ok())
        .map(u16::from_le_bytes);
    // Bits 10:0 of the EtherCAT header are the length.
    ethertype && header.is_some_and(|h| h & 0x07FF == 0)
}

/// Re-opens the frame in `buf` (keeping its MAC addresses).
fn reopen(buf: &mut [u8]) -> Result<FrameBuilder<'_>, ecdc_status> {
    if is_fresh_frame(buf) {
        let mut macs = [0u8; 12];
        if let Some(m) = buf.get(..12) {
            macs.copy_from_slice(m);
        }
        let mut b = FrameBuilder::new(buf).map_err(frame_error)?;
        let (dst, src) = macs.split_at(6);
        if let (Ok(d), Ok(s)) = (<[u8; 6]>::try_from(dst), <[u8; 6]>::try_from(src)) {
            b.set_destination(d);
            b.set_source(s);
        }
        return Ok(b);
    }
    FrameBuilder::resume(buf).map_err(|_| S::ECDC_ERR_FRAME_INVALID)
}

/// Re-opens the frame in `buf`, runs `f`, refreshes `len` and `datagrams`.
fn with_builder<R>(
    fr: &mut ecdc_frame,
    buf: &mut [u8],
    f: impl FnOnce(&mut FrameBuilder<'_>) -> Result<R, ecdc_status>,
) -> Result<R, ecdc_status> {
    let mut b = reopen(buf)?;
    let r = f(&mut b);
    fr.len = b.len();
    fr.datagrams = b.datagram_count();
    r
}

/// Starts a frame in the caller's buffer: Ethernet header (broadcast destination, source
/// 10:10:10:10:10:10, EtherType 0x88A4) and an empty EtherCAT header. `capacity` ≥ 60.
///
/// # Safety
/// `f` is NULL or a writable `ecdc_frame`; `buf` is NULL or valid for writes of `capacity`
/// bytes, stays valid while the frame is used and does not overlap `*f`.
#[no_mangle]
pub unsafe extern "C" fn ecdc_frame_init(
    f: *mut ecdc_frame,
    buf: *mut u8,
    capacity: usize,
) -> ecdc_status {
    if f.is_null() || buf.is_null() {
        return S::ECDC_ERR_NULL;
    }
    // SAFETY: non-null, writable (contract); `write` does not read the old contents.
    unsafe {
        f.write(ecdc_frame {
            buf,
            capacity,
            len: 0,
            datagrams: 0,
        })
    };
    // SAFETY: just written with the caller's buffer, which satisfies frame_parts' contract.
    let (fr, bytes) = match unsafe { frame_parts(f) } {
        Ok(p) => p,
        Err(e) => return e,
    };
    guard(S::ECDC_ERR_PANIC, || match FrameBuilder::new(bytes) {
        Ok(b) => {
            fr.len = b.len();
            fr.datagrams = 0;
            S::ECDC_OK
        }
        Err(e) => frame_error(e),
    })
}

/// Appends one of the host's own datagrams: EtherCAT `command` code (1 = APRD … 14 = FRMW),
/// `index` (keep it outside the machine's `index_first`/`index_count` range), address
/// `adp`/`ado` (for LRD/LWR/LRW the 32-bit logical address is `adp | ado << 16`), `len` data
/// bytes from `data` (NULL = zeros). `*slot` (if not NULL) tells where the datagram is.
/// `ECDC_ERR_FRAME_FULL` when it does not fit (the frame is unchanged).
///
/// # Safety
/// As [`ecdc_frame_init`] for `f`; `data` is NULL or readable for `len` bytes; `slot` is NULL
/// or writable.
#[no_mangle]
pub unsafe extern "C" fn ecdc_frame_push(
    f: *mut ecdc_frame,
    command: u8,
    index: u8,
    adp: u16,
    ado: u16,
    data: *const u8,
    len: u16,
    slot: *mut ecdc_datagram_slot,
) -> ecdc_status {
    // SAFETY: forwarded contract.
    let (fr, bytes) = match unsafe { frame_parts(f) } {
        Ok(p) => p,
        Err(e) => return e,
    };
    let src: Option<&[u8]> = if data.is_null() {
        None
    } else {
        // SAFETY: non-null, readable for `len` bytes (contract).
        Some(unsafe { core::slice::from_raw_parts(data, usize::from(len)) })
    };
    let r = guard(Err(S::ECDC_ERR_PANIC), || {
        let cmd = Command::from_u8(command).map_err(|_| S::ECDC_ERR_ARGUMENT)?;
        let raw = u32::from(adp) | (u32::from(ado) << 16);
        let address = Address::from_raw(cmd, raw);
        with_builder(fr, bytes, |b| {
            let s = match src {
                Some(d) => b.push(cmd, index, address, d),
                None => b.push_zeroed(cmd, index, address, len),
            }
            .map_err(frame_error)?;
            Ok(ecdc_datagram_slot {
                offset: s.offset(),
                data_offset: s.data_offset(),
                wkc_offset: s.data_offset().saturating_add(usize::from(s.len())),
                len: s.len(),
                index: s.index(),
            })
        })
    });
    // SAFETY: `slot` is NULL or writable (contract).
    unsafe { write_out(r, slot) }
}

/// Ends a frame: pads it to 60 bytes and writes its length (the bytes to send are
/// `buf[0..*len)`) to `*len`. `ECDC_ERR_FRAME_EMPTY` without datagrams. The frame can still
/// be appended to afterwards (then finish it again).
///
/// # Safety
/// As [`ecdc_frame_init`] for `f`; `len` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ecdc_frame_finish(f: *mut ecdc_frame, len: *mut usize) -> ecdc_status {
    if len.is_null() {
        return S::ECDC_ERR_NULL;
    }
    // SAFETY: forwarded contract.
    let (fr, bytes) = match unsafe { frame_parts(f) } {
        Ok(p) => p,
        Err(e) => return e,
    };
    let r = guard(Err(S::ECDC_ERR_PANIC), || {
        let b = reopen(bytes)?;
        fr.datagrams = b.datagram_count();
        fr.len = b.len();
        b.finish().map_err(frame_error)
    });
    // SAFETY: `len` is NULL or writable (contract).
    unsafe { write_out(r, len) }
}

/// Appends the machine's datagrams for `now_ns` to the caller's frame (for example its
/// process-data frame); `*appended` (if not NULL) tells whether anything was added. In cyclic
/// operation every call appends the cycle's datagrams: the caller's cadence is the cycle.
/// Datagrams that do not fit wait for the next call.
///
/// # Safety
/// As [`ecdc_start`] for `m`, [`ecdc_frame_init`] for `f`; `appended` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ecdc_poll_transmit_into(
    m: *mut ecdc_machine,
    now_ns: u64,
    f: *mut ecdc_frame,
    appended: *mut bool,
) -> ecdc_status {
    // SAFETY: forwarded contract.
    let (fr, bytes) = match unsafe { frame_parts(f) } {
        Ok(p) => p,
        Err(e) => return e,
    };
    // SAFETY: forwarded contract; the frame buffer is caller memory, disjoint from the machine.
    let r = unsafe {
        with_mut(m, Err, |a| {
            with_builder(fr, bytes, |b| Ok(a.poll_transmit_into(now_ns, b)))
        })
    };
    // SAFETY: `appended` is NULL or writable (contract).
    unsafe { write_out(r, appended) }
}

/// The getters with an optional result: `get`'s value into `*out` and true, or false (with
/// `*out` untouched) when `out` is NULL, `m` is invalid or there is no value.
///
/// # Safety
/// As [`ecdc_start`]; `out` is NULL or writable.
unsafe fn optional_out<T>(
    m: *const ecdc_machine,
    out: *mut T,
    get: impl FnOnce(&dyn Api) -> Option<T>,
) -> bool {
    if out.is_null() {
        return false;
    }
    // SAFETY: forwarded contract.
    match unsafe { with_ref(m, |_| None, get) } {
        Some(v) => {
            // SAFETY: non-null, writable (contract).
            unsafe { out.write(v) };
            true
        }
        None => false,
    }
}

/// When `ecdc_handle_timeout` should be called next: true and `*deadline_ns` set, or false
/// when nothing is scheduled (or `m` is invalid).
///
/// # Safety
/// As [`ecdc_start`]; `deadline_ns` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ecdc_poll_timeout(m: *const ecdc_machine, deadline_ns: *mut u64) -> bool {
    // SAFETY: forwarded contract.
    unsafe { optional_out(m, deadline_ns, |a| a.poll_timeout()) }
}

/// Next event into `*out`: true, or false (and `out->kind = ECDC_EVENT_NONE`) when the queue
/// is empty or an argument is invalid.
///
/// # Safety
/// As [`ecdc_start`]; `out` is NULL or a writable `ecdc_event`.
#[no_mangle]
pub unsafe extern "C" fn ecdc_poll_event(m: *mut ecdc_machine, out: *mut ecdc_event) -> bool {
    if out.is_null() {
        return false;
    }
    // SAFETY: forwarded contract.
    let ev = unsafe { with_mut(m, |_| None, |a| a.poll_event().map(|e| event_to_c(&e))) };
    let found = ev.is_some();
    // SAFETY: non-null, writable (contract).
    unsafe { out.write(ev.unwrap_or_else(ecdc_event::none)) };
    found
}

// ----- input ---------------------------------------------------------------------------------

/// Hands one received Ethernet frame (any bytes) to the machine.
///
/// # Safety
/// As [`ecdc_start`]; `data` is NULL (only with `len` 0) or readable for `len` bytes.
#[no_mangle]
pub unsafe extern "C" fn ecdc_handle_frame(
    m: *mut ecdc_machine,
    now_ns: u64,
    data: *const u8,
    len: usize,
) -> ecdc_status {
    let bytes: &[u8] = if len == 0 {
        &[]
    } else if data.is_null() {
        return S::ECDC_ERR_NULL;
    } else {
        // SAFETY: non-null, readable for `len` bytes (contract).
        unsafe { core::slice::from_raw_parts(data, len) }
    };
    // SAFETY: forwarded contract.
    unsafe {
        with_mut(
            m,
            |e| e,
            |a| {
                a.handle_frame(now_ns, bytes);
                S::ECDC_OK
            },
        )
    }
}

/// Handles the expiry of the time `ecdc_poll_timeout` returned; harmless when nothing expired.
///
/// # Safety
/// As [`ecdc_start`].
#[no_mangle]
pub unsafe extern "C" fn ecdc_handle_timeout(m: *mut ecdc_machine, now_ns: u64) -> ecdc_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_mut(
            m,
            |e| e,
            |a| {
                a.handle_timeout(now_ns);
                S::ECDC_OK
            },
        )
    }
}

// ----- getters -------------------------------------------------------------------------------

/// Current state; `ECDC_STATE_UNKNOWN` for an invalid handle.
///
/// # Safety
/// As [`ecdc_start`].
#[no_mangle]
pub unsafe extern "C" fn ecdc_state(m: *const ecdc_machine) -> ecdc_machine_state {
    // SAFETY: forwarded contract.
    unsafe {
        with_ref(
            m,
            |_| ecdc_machine_state::ECDC_STATE_UNKNOWN,
            |a| state_to_c(a.state()),
        )
    }
}

/// Whether cyclic operation is locked (false for an invalid handle).
///
/// # Safety
/// As [`ecdc_start`].
#[no_mangle]
pub unsafe extern "C" fn ecdc_is_locked(m: *const ecdc_machine) -> bool {
    // SAFETY: forwarded contract.
    unsafe { with_ref(m, |_| false, |a| a.is_locked()) }
}

/// Whether a transmitted frame's datagrams are still awaited (until all came back, the
/// deadline passed, or a reset/start). A host waits on its socket while this is true and may
/// sleep until `ecdc_poll_timeout` otherwise. False for an invalid handle.
///
/// # Safety
/// As [`ecdc_start`].
#[no_mangle]
pub unsafe extern "C" fn ecdc_is_awaiting_reply(m: *const ecdc_machine) -> bool {
    // SAFETY: forwarded contract.
    unsafe { with_ref(m, |_| false, |a| a.is_awaiting_reply()) }
}

/// Last BRD 0x092C upper bound of |Δt| over all slaves (ns): true and `*out` set, or false if
/// none was read in this cyclic run.
///
/// # Safety
/// As [`ecdc_start`]; `out` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ecdc_diff_bound_ns(m: *const ecdc_machine, out: *mut u32) -> bool {
    // SAFETY: forwarded contract.
    unsafe { optional_out(m, out, |a| a.diff_bound_ns()) }
}

/// Reference system time returned by the last cyclic FRMW (ns since 2000-01-01): true and
/// `*out` set, or false.
///
/// # Safety
/// As [`ecdc_start`]; `out` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ecdc_reference_time(m: *const ecdc_machine, out: *mut u64) -> bool {
    // SAFETY: forwarded contract.
    unsafe { optional_out(m, out, |a| a.reference_time()) }
}

/// Copies the counters into `*out`.
///
/// # Safety
/// As [`ecdc_start`]; `out` is NULL or a writable `ecdc_stats`.
#[no_mangle]
pub unsafe extern "C" fn ecdc_get_stats(
    m: *const ecdc_machine,
    out: *mut ecdc_stats,
) -> ecdc_status {
    if out.is_null() {
        return S::ECDC_ERR_NULL;
    }
    // SAFETY: forwarded contract.
    let r = unsafe { with_ref(m, Err, |a| Ok(stats_to_c(&a.stats()))) };
    // SAFETY: `out` is NULL or writable (contract).
    unsafe { write_out(r, out) }
}

/// Number of slaves found by the last bring-up (0 for an invalid handle).
///
/// # Safety
/// As [`ecdc_start`].
#[no_mangle]
pub unsafe extern "C" fn ecdc_slave_count(m: *const ecdc_machine) -> u32 {
    // SAFETY: forwarded contract.
    unsafe {
        with_ref(
            m,
            |_| 0,
            |a| u32::try_from(a.slave_count()).unwrap_or(u32::MAX),
        )
    }
}

/// What the bring-up learnt about the slave at `position`; `ECDC_ERR_CAPACITY` when
/// `position >= ecdc_slave_count(m)`.
///
/// # Safety
/// As [`ecdc_start`]; `out` is NULL or a writable `ecdc_slave`.
#[no_mangle]
pub unsafe extern "C" fn ecdc_slave_info(
    m: *const ecdc_machine,
    position: u32,
    out: *mut ecdc_slave,
) -> ecdc_status {
    if out.is_null() {
        return S::ECDC_ERR_NULL;
    }
    let pos = usize::try_from(position).unwrap_or(usize::MAX);
    // SAFETY: forwarded contract.
    let r = unsafe { with_ref(m, Err, |a| a.slave(pos).ok_or(S::ECDC_ERR_CAPACITY)) };
    // SAFETY: `out` is NULL or writable (contract).
    unsafe { write_out(r, out) }
}
