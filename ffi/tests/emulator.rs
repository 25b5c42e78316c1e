//! A full DC bring-up through the C ABI against the ESC emulator of `ecdc-harness`, in
//! simulated time (the driving of `harness/src/sim.rs`, with every machine call going through
//! the `extern "C"` functions): lock is reached, the slaves' stations and delays are reported
//! through `ecdc_slave_info`, and the host's own cyclic frames with `ecdc_poll_transmit_into`
//! keep the lock.

use core::ptr;

use ecdc_ffi::*;
use ecdc_harness::emu::{Network, Scenario};
use ecdc_harness::sim::DEFAULT_MASTER_EPOCH_NS as EPOCH;

struct InFlight {
    arrival: u64,
    frame: Vec<u8>,
}

/// Drives machine `m` and `net` from true time `t` until an `ECDC_EVENT_LOCKED` event or
/// `limit`; returns the events' kinds and the true time reached.
fn bring_up(
    m: *mut ecdc_machine,
    net: &mut Network,
    mut t: u64,
    limit: u64,
) -> (Vec<ecdc_event_kind>, u64) {
    let mut flight: Vec<InFlight> = Vec::new();
    let mut kinds = Vec::new();
    let mut buf = [0u8; 1514];
    unsafe { assert_eq!(ecdc_start(m, EPOCH + t), ecdc_status::ECDC_OK) };
    while t < limit {
        flight.sort_by_key(|f| f.arrival);
        while flight.first().is_some_and(|f| f.arrival <= t) {
            let f = flight.remove(0);
            let r =
                unsafe { ecdc_handle_frame(m, EPOCH + f.arrival, f.frame.as_ptr(), f.frame.len()) };
            assert_eq!(r, ecdc_status::ECDC_OK);
        }
        unsafe { ecdc_handle_timeout(m, EPOCH + t) };
        for _ in 0..64 {
            let n = unsafe { ecdc_poll_transmit(m, EPOCH + t, buf.as_mut_ptr(), buf.len()) };
            if n == 0 {
                break;
            }
            if let Some(r) = net.transact(&buf[..n], t).unwrap().returned() {
                flight.push(InFlight {
                    arrival: r.arrival.max(t),
                    frame: r.frame,
                });
            }
        }
        let mut ev = ecdc_event::none();
        while unsafe { ecdc_poll_event(m, &mut ev) } {
            kinds.push(ev.kind);
            if ev.kind == ecdc_event_kind::ECDC_EVENT_LOCKED {
                return (kinds, t);
            }
        }
        let mut dl = 0u64;
        let timeout = unsafe { ecdc_poll_timeout(m, &mut dl) }.then(|| dl.saturating_sub(EPOCH));
        let next = flight.iter().map(|f| f.arrival).chain(timeout).min();
        let Some(next) = next else { break };
        t = next.max(t + u64::from(next <= t));
    }
    panic!(
        "no lock by true time {t} ns, events {kinds:?}, state {:?}",
        unsafe { ecdc_state(m) }
    );
}

#[test]
fn four_slave_line_locks_through_the_c_abi_and_rides_in_host_frames() {
    let mut cfg = unsafe { core::mem::zeroed::<ecdc_config>() };
    unsafe { ecdc_config_default(&mut cfg) };
    let mut storage = vec![0u64; ecdc_machine_size().div_ceil(8)];
    let mut m: *mut ecdc_machine = ptr::null_mut();
    let r =
        unsafe { ecdc_machine_init(storage.as_mut_ptr().cast(), storage.len() * 8, &cfg, &mut m) };
    assert_eq!(r, ecdc_status::ECDC_OK);
    let mut net = Network::new(&Scenario::line(4)).unwrap();
    let t0 = net.now();
    let (kinds, mut t) = bring_up(m, &mut net, t0, t0 + 3_000_000_000);
    use ecdc_event_kind as K;
    for want in [
        K::ECDC_EVENT_SLAVES_FOUND,
        K::ECDC_EVENT_DELAYS_MEASURED,
        K::ECDC_EVENT_DRIFT_CONVERGED,
        K::ECDC_EVENT_SYNC_STARTED,
    ] {
        assert!(kinds.contains(&want), "{want:?} missing from {kinds:?}");
    }
    unsafe {
        assert!(ecdc_is_locked(m));
        assert_eq!(ecdc_state(m), ecdc_machine_state::ECDC_STATE_CYCLIC);
        assert_eq!(ecdc_slave_count(m), 4);
        let mut last_delay = None;
        for i in 0..4u32 {
            let mut s = core::mem::zeroed::<ecdc_slave>();
            assert_eq!(ecdc_slave_info(m, i, &mut s), ecdc_status::ECDC_OK);
            assert_eq!(u32::from(s.station), 0x1001 + i);
            assert_eq!(s.is_reference, i == 0);
            assert!(s.offset_written && s.sync_programmed);
            if let Some(d) = last_delay {
                assert!(s.delay_ns > d, "delays grow along the line");
            }
            last_delay = Some(s.delay_ns);
        }
    }

    // The host's cyclic frame: its LRW (index 0x01) plus ecdc's datagrams, one per 1 ms.
    let mut st = ecdc_stats::default();
    unsafe { ecdc_get_stats(m, &mut st) };
    let foreign0 = st.foreign_datagrams;
    // A real bring-up: the static drift compensation alone takes hundreds of FRMW frames.
    assert!(st.has_lock_frames && st.lock_frames > 100, "{st:?}");
    eprintln!(
        "locked after {} frames, {} ms of simulated time",
        st.lock_frames,
        (t - t0) / 1_000_000
    );
    let mut buf = [0u8; 1514];
    for _ in 0..500 {
        t += 1_000_000;
        let mut f = unsafe { core::mem::zeroed::<ecdc_frame>() };
        let mut appended = false;
        let mut len = 0usize;
        unsafe {
            assert_eq!(
                ecdc_frame_init(&mut f, buf.as_mut_ptr(), buf.len()),
                ecdc_status::ECDC_OK
            );
            assert_eq!(
                ecdc_frame_push(
                    &mut f,
                    12,
                    0x01,
                    0,
                    1,
                    [0u8; 32].as_ptr(),
                    32,
                    ptr::null_mut()
                ),
                ecdc_status::ECDC_OK
            );
            assert_eq!(
                ecdc_poll_transmit_into(m, EPOCH + t, &mut f, &mut appended),
                ecdc_status::ECDC_OK
            );
            assert!(appended);
            assert_eq!(ecdc_frame_finish(&mut f, &mut len), ecdc_status::ECDC_OK);
        }
        let r = net
            .transact(&buf[..len], t)
            .unwrap()
            .returned()
            .expect("returned");
        unsafe {
            assert_eq!(
                ecdc_handle_frame(m, EPOCH + r.arrival, r.frame.as_ptr(), r.frame.len()),
                ecdc_status::ECDC_OK
            );
            let mut ev = ecdc_event::none();
            while ecdc_poll_event(m, &mut ev) {
                assert_ne!(ev.kind, K::ECDC_EVENT_ERROR, "{}", ev.text_string());
            }
        }
    }
    unsafe {
        assert!(ecdc_is_locked(m));
        ecdc_get_stats(m, &mut st);
        let mut bound = u32::MAX;
        assert!(ecdc_diff_bound_ns(m, &mut bound));
        assert!(bound <= cfg.lock_ns, "bound {bound} ns");
        ecdc_machine_free(m);
    }
    assert_eq!(
        st.foreign_datagrams - foreign0,
        500,
        "the host's LRW is never used by ecdc"
    );
}
