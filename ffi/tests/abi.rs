//! The C ABI called from Rust as a C caller would: argument checking (NULL, bad handles,
//! storage too small or misaligned, frame buffers too small), the event and state mapping,
//! and the frame builder.

use core::ffi::CStr;
use core::ptr;

use ecdc_core::dc::{Config, Error, Event, State};
use ecdc_core::wire::{Command, EthernetFrame};
use ecdc_ffi::*;

use ecdc_status::*;

fn default_config() -> ecdc_config {
    let mut c = unsafe { core::mem::zeroed::<ecdc_config>() };
    assert_eq!(unsafe { ecdc_config_default(&mut c) }, ECDC_OK);
    c
}

fn new_machine(cfg: &ecdc_config) -> *mut ecdc_machine {
    let mut m: *mut ecdc_machine = ptr::null_mut();
    assert_eq!(unsafe { ecdc_machine_new(cfg, &mut m) }, ECDC_OK);
    assert!(!m.is_null());
    m
}

fn cstr(p: *const core::ffi::c_char) -> &'static str {
    assert!(!p.is_null());
    unsafe { CStr::from_ptr(p) }.to_str().unwrap()
}

/// Storage aligned like the machine, `extra` bytes longer than needed.
fn aligned_storage(size: usize) -> Vec<u64> {
    assert!(ecdc_machine_align() <= 8, "test storage is u64-aligned");
    vec![0u64; size.div_ceil(8) + 1]
}

#[test]
fn version_and_strerror() {
    assert_eq!(cstr(ecdc_version()), env!("CARGO_PKG_VERSION"));
    let mut seen = std::collections::HashSet::new();
    for code in 0..=21 {
        let s = cstr(ecdc_strerror(code));
        assert_ne!(s, "unknown ecdc status code", "code {code}");
        assert!(seen.insert(s), "duplicate text for {code}: {s}");
    }
    assert_eq!(
        cstr(ecdc_strerror(ECDC_ERR_POISONED as i32)),
        "machine poisoned by an earlier panic"
    );
    assert_eq!(cstr(ecdc_strerror(22)), "unknown ecdc status code");
    assert_eq!(cstr(ecdc_strerror(-1)), "unknown ecdc status code");
}

#[test]
fn config_default_mirrors_the_rust_default() {
    assert_eq!(
        unsafe { ecdc_config_default(ptr::null_mut()) },
        ECDC_ERR_NULL
    );
    let c = default_config();
    assert_eq!(config_from_c(&c), Ok(Config::default()));
    assert_eq!(c.station_base, 0x1001);
    assert_eq!((c.index_first, c.index_count), (0x80, 0x80));
    assert_eq!(c.cycle_ns, 1_000_000);
    assert_eq!(c.sync_enabled, 1);
    // A config without SYNC round-trips as `sync: None`.
    let mut n = c;
    n.sync_enabled = 0;
    assert_eq!(config_from_c(&n).unwrap().sync, None);
}

#[test]
fn bad_configs_are_refused_with_their_code() {
    let base = default_config();
    type Edit = fn(&mut ecdc_config);
    let cases: [(Edit, ecdc_status); 7] = [
        (|c| c.index_count = 10, ECDC_ERR_CONFIG_TOO_FEW_INDICES),
        (|c| c.station_base = 0, ECDC_ERR_CONFIG_STATION_RANGE),
        (|c| c.station_base = 0xFF80, ECDC_ERR_CONFIG_STATION_RANGE),
        (
            |c| c.sync_shift_ns = c.sync0_cycle_ns,
            ECDC_ERR_CONFIG_SYNC_CYCLE,
        ),
        (|c| c.cycle_ns = 0, ECDC_ERR_CONFIG_ZERO),
        (|c| c.lock_ns = c.unlock_ns + 1, ECDC_ERR_CONFIG_HYSTERESIS),
        (|c| c.drift_check = 3, ECDC_ERR_CONFIG_ENUM),
    ];
    for (i, (edit, want)) in cases.iter().enumerate() {
        let mut c = base;
        edit(&mut c);
        let mut m: *mut ecdc_machine = ptr::null_mut();
        assert_eq!(unsafe { ecdc_machine_new(&c, &mut m) }, *want, "case {i}");
        assert!(m.is_null(), "case {i}: *out untouched on failure");
        let mut st = aligned_storage(ecdc_machine_size());
        let got =
            unsafe { ecdc_machine_init(st.as_mut_ptr().cast(), ecdc_machine_size(), &c, &mut m) };
        assert_eq!(got, *want, "case {i} (init)");
        assert!(m.is_null());
    }
    let mut c = base;
    c.speed_counter_start = 0x4000;
    let mut m = ptr::null_mut();
    assert_eq!(
        unsafe { ecdc_machine_new(&c, &mut m) },
        ECDC_ERR_CONFIG_SPEED_COUNTER_START
    );
    c = base;
    c.drift_command = 2;
    assert_eq!(
        unsafe { ecdc_machine_new(&c, &mut m) },
        ECDC_ERR_CONFIG_ENUM
    );
    // 0xFC01 + 1024 passes 0xFFFF only for the large capacity.
    c = base;
    c.station_base = 0xFC01;
    let ok = new_machine(&c);
    unsafe { ecdc_machine_free(ok) };
    assert_eq!(
        unsafe { ecdc_machine_new_large(&c, &mut m) },
        ECDC_ERR_CONFIG_STATION_RANGE
    );
}

#[test]
fn new_and_free_with_null_arguments() {
    let c = default_config();
    let mut m: *mut ecdc_machine = ptr::null_mut();
    assert_eq!(
        unsafe { ecdc_machine_new(ptr::null(), &mut m) },
        ECDC_ERR_NULL
    );
    assert_eq!(
        unsafe { ecdc_machine_new(&c, ptr::null_mut()) },
        ECDC_ERR_NULL
    );
    assert_eq!(
        unsafe { ecdc_machine_new_large(ptr::null(), &mut m) },
        ECDC_ERR_NULL
    );
    unsafe { ecdc_machine_free(ptr::null_mut()) };
    // Creating the 1024-slave machine builds it by value (Machine::new) before moving it into
    // its allocation: in this unoptimised test build that passes several 230 KiB copies over
    // the stack, more than a test thread's 2 MiB. A C host calls it on its main thread (8 MiB
    // by default); docs/c-api.md states the need.
    let c2 = c;
    let big_thread = std::thread::Builder::new()
        .stack_size(32 << 20)
        .spawn(move || {
            let mut m: *mut ecdc_machine = ptr::null_mut();
            assert_eq!(unsafe { ecdc_machine_new_large(&c2, &mut m) }, ECDC_OK);
            m as usize
        })
        .unwrap();
    let big = big_thread.join().unwrap() as *mut ecdc_machine;
    assert_eq!(unsafe { ecdc_machine_capacity(big) }, ECDC_MAX_SLAVES_LARGE);
    assert_eq!(
        unsafe { ecdc_state(big) },
        ecdc_machine_state::ECDC_STATE_IDLE
    );
    unsafe { ecdc_machine_free(big) };
}

#[test]
fn init_refuses_small_or_misaligned_storage() {
    let c = default_config();
    let size = ecdc_machine_size();
    let align = ecdc_machine_align();
    assert!(size > 0 && align.is_power_of_two());
    assert!(ecdc_machine_size_large() > size);
    let mut st = aligned_storage(size);
    let base: *mut u8 = st.as_mut_ptr().cast();
    let mut m: *mut ecdc_machine = ptr::null_mut();
    let r = unsafe { ecdc_machine_init(base.cast(), size - 1, &c, &mut m) };
    assert_eq!(r, ECDC_ERR_STORAGE_TOO_SMALL);
    let r = unsafe { ecdc_machine_init(base.add(1).cast(), size, &c, &mut m) };
    assert_eq!(r, ECDC_ERR_STORAGE_MISALIGNED);
    let r = unsafe { ecdc_machine_init(ptr::null_mut(), size, &c, &mut m) };
    assert_eq!(r, ECDC_ERR_NULL);
    let r = unsafe { ecdc_machine_init(base.cast(), size, ptr::null(), &mut m) };
    assert_eq!(r, ECDC_ERR_NULL);
    let r = unsafe { ecdc_machine_init(base.cast(), size, &c, ptr::null_mut()) };
    assert_eq!(r, ECDC_ERR_NULL);
    assert!(m.is_null());
    // The standard storage is too small for the large capacity.
    let r = unsafe { ecdc_machine_init_large(base.cast(), size, &c, &mut m) };
    assert_eq!(r, ECDC_ERR_STORAGE_TOO_SMALL);

    let r = unsafe { ecdc_machine_init(base.cast(), size, &c, &mut m) };
    assert_eq!(r, ECDC_OK);
    assert_eq!(m.cast::<u8>(), base, "the handle is the storage");
    assert_eq!(unsafe { ecdc_machine_capacity(m) }, ECDC_MAX_SLAVES);
    assert_eq!(unsafe { ecdc_start(m, 1_000) }, ECDC_OK);
    assert_eq!(
        unsafe { ecdc_state(m) },
        ecdc_machine_state::ECDC_STATE_COUNT_SLAVES
    );
    unsafe { ecdc_machine_free(m) };
    // Freed caller storage is no longer a handle; a second free is ignored.
    assert_eq!(unsafe { ecdc_start(m, 2_000) }, ECDC_ERR_INVALID_HANDLE);
    assert_eq!(
        unsafe { ecdc_state(m) },
        ecdc_machine_state::ECDC_STATE_UNKNOWN
    );
    unsafe { ecdc_machine_free(m) };
    // The storage can be reused for a new machine.
    assert_eq!(
        unsafe { ecdc_machine_init(base.cast(), size, &c, &mut m) },
        ECDC_OK
    );
    unsafe { ecdc_machine_free(m) };
}

#[test]
fn every_machine_call_refuses_null_and_foreign_handles() {
    let mut zeroed = aligned_storage(ecdc_machine_size());
    let foreign: *mut ecdc_machine = zeroed.as_mut_ptr().cast();
    for (m, want) in [
        (ptr::null_mut(), ECDC_ERR_NULL),
        (foreign, ECDC_ERR_INVALID_HANDLE),
    ] {
        unsafe {
            assert_eq!(ecdc_start(m, 0), want);
            assert_eq!(ecdc_reset(m), want);
            assert_eq!(ecdc_request_delay_measurement(m), want);
            assert_eq!(ecdc_set_slave_t_diff(m, 0, 10), want);
            assert_eq!(ecdc_clear_slave_t_diff(m, 0), want);
            assert_eq!(ecdc_handle_timeout(m, 0), want);
            assert_eq!(ecdc_handle_frame(m, 0, [0u8; 60].as_ptr(), 60), want);
            let mut buf = [0u8; 1514];
            assert_eq!(ecdc_poll_transmit(m, 0, buf.as_mut_ptr(), buf.len()), 0);
            let mut t = 7u64;
            assert!(!ecdc_poll_timeout(m, &mut t));
            assert_eq!(t, 7);
            let mut ev = ecdc_event::none();
            ev.kind = ecdc_event_kind::ECDC_EVENT_LOCKED;
            assert!(!ecdc_poll_event(m, &mut ev));
            assert_eq!(ev.kind, ecdc_event_kind::ECDC_EVENT_NONE);
            assert_eq!(ecdc_state(m), ecdc_machine_state::ECDC_STATE_UNKNOWN);
            assert!(!ecdc_is_locked(m));
            let mut s = ecdc_stats::default();
            assert_eq!(ecdc_get_stats(m, &mut s), want);
            assert_eq!(ecdc_slave_count(m), 0);
            assert_eq!(ecdc_machine_capacity(m), 0);
            let mut f = core::mem::zeroed::<ecdc_frame>();
            assert_eq!(
                ecdc_frame_init(&mut f, buf.as_mut_ptr(), buf.len()),
                ECDC_OK
            );
            let mut appended = true;
            assert_eq!(ecdc_poll_transmit_into(m, 0, &mut f, &mut appended), want);
            assert!(appended, "untouched on failure");
            ecdc_machine_free(m); // ignored
        }
    }
    // NULL out-pointers on a live machine.
    let m = new_machine(&default_config());
    unsafe {
        assert!(!ecdc_poll_timeout(m, ptr::null_mut()));
        assert!(!ecdc_poll_event(m, ptr::null_mut()));
        assert_eq!(ecdc_get_stats(m, ptr::null_mut()), ECDC_ERR_NULL);
        assert_eq!(ecdc_slave_info(m, 0, ptr::null_mut()), ECDC_ERR_NULL);
        assert_eq!(ecdc_handle_frame(m, 0, ptr::null(), 10), ECDC_ERR_NULL);
        assert_eq!(ecdc_handle_frame(m, 0, ptr::null(), 0), ECDC_OK);
        assert_eq!(ecdc_poll_transmit(m, 0, ptr::null_mut(), 1514), 0);
        assert_eq!(
            ecdc_poll_transmit_into(m, 0, ptr::null_mut(), ptr::null_mut()),
            ECDC_ERR_NULL
        );
        assert_eq!(ecdc_set_slave_t_diff(m, 256, 10), ECDC_ERR_CAPACITY);
        assert_eq!(ecdc_set_slave_t_diff(m, 255, 10), ECDC_OK);
        let mut si = core::mem::zeroed::<ecdc_slave>();
        assert_eq!(ecdc_slave_info(m, 0, &mut si), ECDC_ERR_CAPACITY);
        ecdc_machine_free(m);
    }
}

#[test]
fn poll_transmit_writes_the_count_frame_and_reports_a_small_buffer() {
    let c = default_config();
    let m = new_machine(&c);
    let mut buf = [0u8; 1514];
    unsafe {
        assert_eq!(
            ecdc_poll_transmit(m, 1_000, buf.as_mut_ptr(), buf.len()),
            0,
            "idle"
        );
        assert_eq!(ecdc_start(m, 1_000), ECDC_OK);
        // Too small: nothing written, a BUFFER_TOO_SMALL fault event.
        assert_eq!(ecdc_poll_transmit(m, 1_000, buf.as_mut_ptr(), 59), 0);
        let mut ev = ecdc_event::none();
        assert!(ecdc_poll_event(m, &mut ev));
        assert_eq!(ev.kind, ecdc_event_kind::ECDC_EVENT_ERROR);
        assert_eq!(
            ev.u.error.kind,
            ecdc_fault_kind::ECDC_FAULT_BUFFER_TOO_SMALL
        );
        assert_eq!(ev.text_string(), "error: transmit buffer too small");
        let n = ecdc_poll_transmit(m, 1_000, buf.as_mut_ptr(), buf.len());
        assert!(n >= 60, "{n}");
        let eth = EthernetFrame::new_checked(&buf[..n]).unwrap();
        let frame = eth.ecat_frame().unwrap();
        let d: Vec<_> = frame.iter().map(|d| d.unwrap()).collect();
        assert_eq!(d.len(), 1);
        assert_eq!(d[0].command(), Ok(Command::Brd));
        assert!(
            d[0].index() >= 0x80,
            "index {:#x} in the machine's range",
            d[0].index()
        );
        let mut t = 0;
        assert!(ecdc_poll_timeout(m, &mut t));
        assert_eq!(t, 1_000 + c.response_timeout_ns);
        let mut s = ecdc_stats::default();
        assert_eq!(ecdc_get_stats(m, &mut s), ECDC_OK);
        assert_eq!(s.frames_sent, 1);
        // No reply by the deadline: a timeout is counted and the request resent.
        assert_eq!(ecdc_handle_timeout(m, t), ECDC_OK);
        assert_eq!(ecdc_get_stats(m, &mut s), ECDC_OK);
        assert_eq!(s.timeouts, 1);
        ecdc_machine_free(m);
    }
}

#[test]
fn frame_builder_carries_host_and_machine_datagrams() {
    let m = new_machine(&default_config());
    let mut buf = [0u8; 1514];
    let mut f = unsafe { core::mem::zeroed::<ecdc_frame>() };
    unsafe {
        assert_eq!(
            ecdc_frame_init(ptr::null_mut(), buf.as_mut_ptr(), 1514),
            ECDC_ERR_NULL
        );
        assert_eq!(
            ecdc_frame_init(&mut f, ptr::null_mut(), 1514),
            ECDC_ERR_NULL
        );
        assert_eq!(
            ecdc_frame_init(&mut f, buf.as_mut_ptr(), 59),
            ECDC_ERR_BUFFER_TOO_SMALL
        );
        assert_eq!(
            ecdc_frame_init(&mut f, buf.as_mut_ptr(), buf.len()),
            ECDC_OK
        );
        assert_eq!((f.len, f.datagrams), (16, 0));
        let mut len = 0usize;
        assert_eq!(ecdc_frame_finish(&mut f, &mut len), ECDC_ERR_FRAME_EMPTY);
        assert_eq!(ecdc_frame_finish(&mut f, ptr::null_mut()), ECDC_ERR_NULL);
        // Unknown command code; an LRW longer than a datagram can carry.
        let mut slot = ecdc_datagram_slot::default();
        assert_eq!(
            ecdc_frame_push(&mut f, 15, 1, 0, 0, ptr::null(), 4, &mut slot),
            ECDC_ERR_ARGUMENT
        );
        assert_eq!(
            ecdc_frame_push(&mut f, 12, 1, 0, 0, ptr::null(), 1487, &mut slot),
            ECDC_ERR_ARGUMENT
        );
        // The host's process data: LRW of 32 bytes at logical 0x00010000, index 0x01.
        let pd = [0xA5u8; 32];
        assert_eq!(
            ecdc_frame_push(&mut f, 12, 0x01, 0x0000, 0x0001, pd.as_ptr(), 32, &mut slot),
            ECDC_OK
        );
        assert_eq!(
            (slot.offset, slot.data_offset, slot.len, slot.index),
            (16, 26, 32, 1)
        );
        assert_eq!(slot.wkc_offset, 58);
        assert_eq!((f.len, f.datagrams), (60, 1));
        assert_eq!(ecdc_start(m, 5_000), ECDC_OK);
        let mut appended = false;
        assert_eq!(
            ecdc_poll_transmit_into(m, 5_000, &mut f, &mut appended),
            ECDC_OK
        );
        assert!(appended);
        assert_eq!(f.datagrams, 2);
        assert_eq!(ecdc_frame_finish(&mut f, &mut len), ECDC_OK);
        assert_eq!(len, f.len.max(60));
        let eth = EthernetFrame::new_checked(&buf[..len]).unwrap();
        let frame = eth.ecat_frame().unwrap();
        let d: Vec<_> = frame.iter().map(|d| d.unwrap()).collect();
        assert_eq!(d.len(), 2);
        assert_eq!(d[0].command(), Ok(Command::Lrw));
        assert_eq!(d[0].data(), &pd[..]);
        assert!(d[0].more());
        assert_eq!(d[1].command(), Ok(Command::Brd));
        assert!(d[1].index() >= 0x80);
        // Fill the frame: a datagram that does not fit is refused and the frame is unchanged.
        let before = buf;
        let r = ecdc_frame_push(&mut f, 12, 2, 0, 0, ptr::null(), 1486, ptr::null_mut());
        assert_eq!(r, ECDC_ERR_FRAME_FULL);
        assert_eq!(buf, before);
        assert_eq!(f.datagrams, 2);
        // A buffer that holds no frame is refused.
        let mut junk = [0x55u8; 100];
        let mut g = ecdc_frame {
            buf: junk.as_mut_ptr(),
            capacity: junk.len(),
            len: 0,
            datagrams: 0,
        };
        assert_eq!(
            ecdc_frame_push(&mut g, 7, 1, 0, 0, ptr::null(), 2, ptr::null_mut()),
            ECDC_ERR_FRAME_INVALID
        );
        assert_eq!(
            ecdc_poll_transmit_into(m, 5_000, &mut g, ptr::null_mut()),
            ECDC_ERR_FRAME_INVALID
        );
        g.capacity = 10;
        assert_eq!(
            ecdc_frame_finish(&mut g, &mut len),
            ECDC_ERR_BUFFER_TOO_SMALL
        );
        ecdc_machine_free(m);
    }
}

#[test]
fn states_map_to_their_names() {
    for s in State::ALL {
        let c = state_to_c(s);
        assert_ne!(
            c,
            ecdc_machine_state::ECDC_STATE_UNKNOWN,
            "{s:?} needs an ABI number"
        );
        assert_eq!(cstr(ecdc_state_name(c as i32)), s.name(), "{s:?}");
    }
    assert_eq!(cstr(ecdc_state_name(255)), "unknown");
    assert_eq!(cstr(ecdc_state_name(-3)), "unknown");
}

#[test]
fn events_map_to_tagged_structs() {
    use ecdc_event_kind as K;
    let e = event_to_c(&Event::SlavesFound { count: 7, dc: 5 });
    assert_eq!(e.kind, K::ECDC_EVENT_SLAVES_FOUND);
    assert_eq!(
        unsafe { e.u.slaves_found },
        ecdc_ev_slaves_found { count: 7, dc: 5 }
    );
    assert_eq!(e.text_string(), "7 slaves found, 5 with a DC system time");
    let e = event_to_c(&Event::Locked {
        frames: 1234,
        bound_ns: 88,
    });
    assert_eq!(e.kind, K::ECDC_EVENT_LOCKED);
    assert_eq!(
        unsafe { e.u.locked },
        ecdc_ev_locked {
            frames: 1234,
            bound_ns: 88
        }
    );
    let e = event_to_c(&Event::SyncStarted {
        start: ecdc_core::time::SystemTime(1 << 60),
        slaves: 3,
    });
    assert_eq!(
        unsafe { e.u.sync_started },
        ecdc_ev_sync_started {
            start: 1 << 60,
            slaves: 3
        }
    );
    let e = event_to_c(&Event::Restarting);
    assert_eq!(e.kind, K::ECDC_EVENT_RESTARTING);
    assert_eq!(unsafe { e.u.raw }, [0; 4]);
    let cases = [
        (
            Event::DelaysMeasured { max_delay_ns: 1 },
            K::ECDC_EVENT_DELAYS_MEASURED,
        ),
        (
            Event::OffsetsWritten {
                written: 1,
                skipped_running: 0,
            },
            K::ECDC_EVENT_OFFSETS_WRITTEN,
        ),
        (
            Event::DriftConverged {
                frames: 1,
                max_diff_ns: 2,
            },
            K::ECDC_EVENT_DRIFT_CONVERGED,
        ),
        (Event::LockLost { bound_ns: 9 }, K::ECDC_EVENT_LOCK_LOST),
        (
            Event::DelaysUpdated { max_change_ns: 3 },
            K::ECDC_EVENT_DELAYS_UPDATED,
        ),
    ];
    for (ev, kind) in cases {
        let e = event_to_c(&ev);
        assert_eq!(e.kind, kind, "{ev:?}");
        assert!(!e.text_string().is_empty());
    }
    // Faults: flattened fields and the core's own description.
    let e = event_to_c(&Event::Error(Error::Wkc {
        command: Command::Fprd,
        station: 0x1002,
        register: 0x092C,
        expected: 1,
        actual: 0,
    }));
    assert_eq!(e.kind, K::ECDC_EVENT_ERROR);
    let f = unsafe { e.u.error };
    assert_eq!(f.kind, ecdc_fault_kind::ECDC_FAULT_WKC);
    assert_eq!(
        (f.command, f.station, f.register_, f.expected, f.actual),
        (4, 0x1002, 0x092C, 1, 0)
    );
    assert!(
        e.text_string().starts_with("error: FPRD station 0x1002"),
        "{}",
        e.text_string()
    );
    let f = fault_to_c(&Error::Timeout {
        state: State::LatchTrigger,
    });
    assert_eq!(f.kind, ecdc_fault_kind::ECDC_FAULT_TIMEOUT);
    assert_eq!(f.state, ecdc_machine_state::ECDC_STATE_LATCH_TRIGGER);
    let f = fault_to_c(&Error::NotConverged {
        frames: 30_000,
        slaves_over: 2,
        worst_station: 0x1003,
        worst_diff_ns: 900,
    });
    assert_eq!(
        (f.kind, f.count, f.actual, f.station, f.diff_ns),
        (
            ecdc_fault_kind::ECDC_FAULT_NOT_CONVERGED,
            30_000,
            2,
            0x1003,
            900
        )
    );
    let f = fault_to_c(&Error::TooManySlaves {
        found: 300,
        capacity: 256,
    });
    assert_eq!((f.actual, f.expected), (300, 256));
}

#[test]
fn event_text_is_truncated_at_a_character_boundary() {
    let e = event_to_c(&Event::Error(Error::NotConverged {
        frames: u32::MAX,
        slaves_over: u16::MAX,
        worst_station: u16::MAX,
        worst_diff_ns: u32::MAX,
    }));
    assert_eq!(e.text[ECDC_EVENT_TEXT_LEN - 1], 0);
    // This text is longer than the buffer: it is cut to exactly the room before the NUL.
    assert_eq!(e.text_string().len(), ECDC_EVENT_TEXT_LEN - 1);
    assert!(e
        .text_string()
        .starts_with("error: static drift compensation not converged"));
}
