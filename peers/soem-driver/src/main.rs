//! Drives emulated (or real) slaves with the real SOEM master (SOEM 1.3.3's C sources as the
//! SOEM-sys 0.2.0 crate bundles and builds them), Distributed Clocks set up exactly as SOEM's
//! own Linux samples do (`test/linux/ebox/ebox.c`, `test/linux/red_test/red_test.c` in those
//! sources; README.md lists the steps). GPL-2.0-only, like SOEM.
//!
//! It uses SOEM's single-context API (`ec_*` and the `ec_slave`, `ec_group`, `ec_DCtime`
//! globals), the one the samples use. SOEM-sys generates bindings only for functions and types,
//! so the globals and the three `ec_config*` calls its bindgen run left out are declared here
//! from SOEM's headers (ethercatmain.h, ethercatconfig.h).
//!
//! It measures nothing itself: run it against `ecdc emulate --json`, whose yardstick reports
//! what the SYNC0 pulses did (scripts/peers-bench.sh). It prints, on stderr, what SOEM found
//! (identities from SII, propagation delays), the bring-up times, the cycle count, cycles whose
//! working counter was short, and the samples' PI error on `ec_DCtime`.
//!
//! Usage: soem-driver IFACE [SECONDS] [CYCLE_US]   (defaults: 10 s, 1000 us)
//!        soem-driver IFACE --config-only          (ec_config_init + ec_config_map + ec_configdc)

#[path = "../../common/arg.rs"]
mod arg;

use std::ffi::{CStr, CString};
use std::os::raw::{c_int, c_void};
use std::ptr::addr_of_mut;
use std::sync::atomic::{AtomicBool, AtomicI32, AtomicI64, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use arg::arg;
use soem_sys::{
    boolean, ec_close, ec_configdc, ec_dcsync0, ec_groupt, ec_init, ec_receive_processdata,
    ec_send_processdata, ec_slavet, ec_state_EC_STATE_OPERATIONAL, ec_state_EC_STATE_SAFE_OP,
    ec_statecheck, ec_writestate,
};

/// `EC_MAXSLAVE` of SOEM 1.3.3 (ethercatmain.h): the size of `ec_slave[]`; entry 0 is the
/// master's summary of all slaves.
const EC_MAXSLAVE: usize = 200;
/// `EC_MAXGROUP` (ethercatmain.h).
const EC_MAXGROUP: usize = 2;
/// `EC_TIMEOUTRET`, µs (ethercattype.h): the samples' receive timeout for process data.
const EC_TIMEOUTRET: c_int = 2000;
/// `EC_TIMEOUTSTATE`, µs (ethercattype.h).
const EC_TIMEOUTSTATE: c_int = 2_000_000;
/// The samples' IOmap size (`char IOmap[4096]` in red_test.c and ebox.c).
const IOMAP_LEN: usize = 4096;
const NSEC_PER_SEC: i64 = 1_000_000_000;

#[allow(non_upper_case_globals)]
extern "C" {
    static mut ec_slave: [ec_slavet; EC_MAXSLAVE];
    static mut ec_slavecount: c_int;
    static mut ec_group: [ec_groupt; EC_MAXGROUP];
    static mut ec_DCtime: i64;
    fn ec_config_init(usetable: u8) -> c_int;
    fn ec_config_map(p_iomap: *mut c_void) -> c_int;
}

/// The samples' IOmap, handed to SOEM once; only SOEM touches it afterwards.
static mut IOMAP: [u8; IOMAP_LEN] = [0; IOMAP_LEN];

const FALSE: boolean = 0;
const TRUE: boolean = 1;

fn slave(i: usize) -> &'static ec_slavet {
    assert!(i < EC_MAXSLAVE);
    // SAFETY: in bounds; SOEM writes the entries during configuration and state checks, which
    // happen on the main thread; the cyclic thread calls this once, before its loop.
    unsafe { &*addr_of_mut!(ec_slave).cast::<ec_slavet>().add(i) }
}

fn slave_count() -> usize {
    // SAFETY: plain read of SOEM's global, written by ec_config_init on this thread.
    let n = unsafe { ec_slavecount };
    usize::try_from(n).unwrap_or(0).min(EC_MAXSLAVE - 1)
}

fn name(s: &ec_slavet) -> String {
    // SAFETY: SOEM NUL-terminates the name it copies from SII (ecx_siistring).
    unsafe { CStr::from_ptr(s.name.as_ptr()) }
        .to_string_lossy()
        .into_owned()
}

fn ms(t: Instant) -> u128 {
    t.elapsed().as_millis()
}

fn main() {
    let r = run();
    if let Err(e) = r {
        eprintln!("soem-driver: {e}");
        std::process::exit(1);
    }
}

/// The samples' `ec_sync` (red_test.c, ebox.c), verbatim in Rust: the master's cycle start is
/// moved by `offsettime` so that it lands 50 µs after a DC cycle boundary of the reference
/// clock. `integral` is the samples' static.
fn ec_sync(reftime: i64, cycletime: i64, integral: &mut i64) -> (i64, i64) {
    // "set linux sync point 50us later than DC sync, just as example"
    let mut delta = (reftime - 50_000) % cycletime;
    if delta > cycletime / 2 {
        delta -= cycletime;
    }
    if delta > 0 {
        *integral += 1;
    }
    if delta < 0 {
        *integral -= 1;
    }
    (-(delta / 100) - (*integral / 20), delta)
}

/// red_test.c's `add_timespec`.
fn add_timespec(ts: &mut libc::timespec, addtime: i64) {
    let nsec = addtime % NSEC_PER_SEC;
    let sec = (addtime - nsec) / NSEC_PER_SEC;
    ts.tv_sec += sec;
    ts.tv_nsec += nsec;
    if ts.tv_nsec > NSEC_PER_SEC {
        let nsec = ts.tv_nsec % NSEC_PER_SEC;
        ts.tv_sec += (ts.tv_nsec - nsec) / NSEC_PER_SEC;
        ts.tv_nsec = nsec;
    }
}

/// What the cyclic thread tells the main thread.
#[derive(Default)]
struct Cyclic {
    dorun: AtomicBool,
    stop: AtomicBool,
    cycles: AtomicU64,
    wkc: AtomicI32,
    short_wkc: AtomicU64,
    /// The PI's delta (`gl_delta` in red_test.c) and its statistics since the last reset.
    delta: AtomicI64,
    delta_abs_sum: AtomicI64,
    delta_abs_max: AtomicI64,
    delta_n: AtomicI64,
    /// Latest wake-up after the programmed cycle start, ns.
    late_max: AtomicI64,
}

impl Cyclic {
    fn reset_delta_stats(&self) {
        self.delta_abs_sum.store(0, Ordering::Relaxed);
        self.delta_abs_max.store(0, Ordering::Relaxed);
        self.delta_n.store(0, Ordering::Relaxed);
        self.late_max.store(0, Ordering::Relaxed);
    }
}

/// red_test.c's `ecatthread`: receive, PI on ec_DCtime, send, sleep to the shifted cycle start.
/// The samples run it under SCHED_FIFO; here it runs SCHED_OTHER like the other masters in
/// scripts/peers-bench.sh, so no master gets a scheduling advantage.
fn ecatthread(c: &Cyclic, cycletime: i64, expected_wkc: i32) {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: valid pointer to a timespec.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    // "round to nearest ms"
    let ht = ts.tv_nsec / 1_000_000 + 1;
    ts.tv_nsec = ht * 1_000_000;
    let mut toff = 0i64;
    let mut integral = 0i64;
    // ec_configdc set it before this thread started; read once so this thread never looks at
    // ec_slave[] while the main thread's state checks write it.
    let hasdc = slave(0).hasdc != FALSE;
    // SAFETY: SOEM's process-data calls; this thread is the only one making them while it
    // runs (the main thread only does state reads/writes, as in the samples, and SOEM guards
    // its frame buffers with its own mutexes).
    unsafe { ec_send_processdata() };
    while !c.stop.load(Ordering::Relaxed) {
        add_timespec(&mut ts, cycletime + toff);
        // SAFETY: valid timespec; absolute sleep on CLOCK_MONOTONIC as in red_test.c.
        unsafe {
            libc::clock_nanosleep(
                libc::CLOCK_MONOTONIC,
                libc::TIMER_ABSTIME,
                &ts,
                std::ptr::null_mut(),
            )
        };
        let mut now = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: valid pointer.
        unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut now) };
        let late = (now.tv_sec - ts.tv_sec) * NSEC_PER_SEC + (now.tv_nsec - ts.tv_nsec);
        c.late_max.fetch_max(late, Ordering::Relaxed);
        if c.dorun.load(Ordering::Relaxed) {
            // SAFETY: see above.
            let wkc = unsafe { ec_receive_processdata(EC_TIMEOUTRET) };
            c.wkc.store(wkc, Ordering::Relaxed);
            if wkc < expected_wkc {
                c.short_wkc.fetch_add(1, Ordering::Relaxed);
            }
            c.cycles.fetch_add(1, Ordering::Relaxed);
            if hasdc {
                // SAFETY: ec_DCtime is written by ec_receive_processdata on this thread.
                let dctime = unsafe { ec_DCtime };
                let (off, delta) = ec_sync(dctime, cycletime, &mut integral);
                toff = off;
                c.delta.store(delta, Ordering::Relaxed);
                c.delta_abs_sum.fetch_add(delta.abs(), Ordering::Relaxed);
                c.delta_abs_max.fetch_max(delta.abs(), Ordering::Relaxed);
                c.delta_n.fetch_add(1, Ordering::Relaxed);
            }
            // SAFETY: see above.
            unsafe { ec_send_processdata() };
        }
    }
}

fn run() -> Result<(), String> {
    let iface: String = std::env::args()
        .nth(1)
        .ok_or("usage: soem-driver IFACE [SECONDS] [CYCLE_US] | IFACE --config-only")?;
    let config_only = std::env::args().nth(2).as_deref() == Some("--config-only");
    let (seconds, cycle_us): (f64, u32) = if config_only {
        (0.0, 1000)
    } else {
        (arg(2, 10.0)?, arg(3, 1000)?)
    };
    if cycle_us == 0 || cycle_us > 1_000_000 {
        return Err(format!("cycle {cycle_us} us: must be 1..=1000000"));
    }
    let cycletime = i64::from(cycle_us) * 1000;
    let ifname = CString::new(iface.clone()).map_err(|_| "interface name has a NUL")?;

    let started = Instant::now();
    // SAFETY: NUL-terminated name; SOEM opens a raw socket on it.
    if unsafe { ec_init(ifname.as_ptr()) } <= 0 {
        return Err(format!("ec_init on {iface} failed (needs CAP_NET_RAW)"));
    }
    // SAFETY: SOEM's configuration calls, on this thread only; IOMAP is handed to SOEM here
    // once and never touched by Rust afterwards.
    let found = unsafe { ec_config_init(FALSE) };
    if found <= 0 {
        unsafe { ec_close() };
        return Err("ec_config_init: no slaves found".into());
    }
    let n = slave_count();
    eprintln!(
        "soem-driver: ec_config_init found {n} slaves ({} ms)",
        ms(started)
    );
    let iomap_used = unsafe { ec_config_map(addr_of_mut!(IOMAP).cast::<c_void>()) };
    let dc = unsafe { ec_configdc() };
    eprintln!(
        "soem-driver: ec_config_map {iomap_used} bytes, ec_configdc {} ({} ms)",
        if dc != FALSE {
            "found DC slaves"
        } else {
            "found no DC slave"
        },
        ms(started)
    );
    for i in 1..=n {
        let s = slave(i);
        eprintln!(
            "soem-driver: slave {i}: vendor 0x{:08x} product 0x{:08x} rev 0x{:08x} name {:?} \
             out {} in {} bits, DC {} pdelay {} ns",
            s.eep_man,
            s.eep_id,
            s.eep_rev,
            name(s),
            s.Obits,
            s.Ibits,
            s.hasdc,
            s.pdelay
        );
    }
    if config_only {
        unsafe { ec_close() };
        return Ok(());
    }

    // "wait for all slaves to reach SAFE_OP state"
    let safe = unsafe { ec_statecheck(0, ec_state_EC_STATE_SAFE_OP as u16, EC_TIMEOUTSTATE * 4) };
    eprintln!(
        "soem-driver: state 0x{safe:02x} after the SAFE-OP check ({} ms)",
        ms(started)
    );
    // SAFETY: ec_group[0] was filled by ec_config_map on this thread.
    let g0 = unsafe { &*addr_of_mut!(ec_group).cast::<ec_groupt>() };
    let expected_wkc = i32::from(g0.outputsWKC) * 2 + i32::from(g0.inputsWKC);
    eprintln!("soem-driver: expected working counter {expected_wkc}");

    let c = Arc::new(Cyclic::default());
    let thread = {
        let c = Arc::clone(&c);
        std::thread::Builder::new()
            .name("ecatthread".into())
            .spawn(move || ecatthread(&c, cycletime, expected_wkc))
            .map_err(|e| format!("spawning the cyclic thread: {e}"))?
    };

    // red_test.c: request OP, activate the cyclic process data, wait for OP.
    let op_request = Instant::now();
    unsafe {
        (*addr_of_mut!(ec_slave).cast::<ec_slavet>()).state = ec_state_EC_STATE_OPERATIONAL as u16;
        ec_writestate(0);
    }
    c.dorun.store(true, Ordering::Relaxed);
    unsafe { ec_statecheck(0, ec_state_EC_STATE_OPERATIONAL as u16, 5 * EC_TIMEOUTSTATE) };
    let result = if u32::from(slave(0).state) != ec_state_EC_STATE_OPERATIONAL {
        let mut bad = Vec::new();
        for i in 1..=n {
            let s = slave(i);
            if u32::from(s.state) != ec_state_EC_STATE_OPERATIONAL {
                bad.push(format!(
                    "slave {i} state 0x{:02x} AL status 0x{:04x}",
                    s.state, s.ALstatuscode
                ));
            }
        }
        Err(format!("not all slaves reached OP: {}", bad.join("; ")))
    } else {
        eprintln!(
            "soem-driver: all slaves in OP after {} ms ({} ms since start)",
            ms(op_request),
            ms(started)
        );
        // ebox.c: "wait for linux to sync on DC", then SYNC0 on (every DC slave here; ebox has
        // one), cycle = the master's cycle, shift 0.
        std::thread::sleep(Duration::from_millis(100));
        let mut synced = 0;
        for i in 1..=n {
            if slave(i).hasdc != FALSE {
                unsafe { ec_dcsync0(i as u16, TRUE, cycletime as u32, 0) };
                synced += 1;
            }
        }
        eprintln!(
            "soem-driver: ec_dcsync0 on {synced} slaves ({} ms since start)",
            ms(started)
        );
        let sync_on = Instant::now();
        let cycles0 = c.cycles.load(Ordering::Relaxed);
        let short0 = c.short_wkc.load(Ordering::Relaxed);
        let until = sync_on + Duration::from_secs_f64(seconds.max(0.0));
        // Report the PI's error over the second half, where it has settled (if it does).
        let half = sync_on + Duration::from_secs_f64(seconds.max(0.0) / 2.0);
        let mut reset = false;
        while Instant::now() < until {
            std::thread::sleep(Duration::from_millis(10));
            if !reset && Instant::now() >= half {
                c.reset_delta_stats();
                reset = true;
            }
        }
        let cycles = c.cycles.load(Ordering::Relaxed) - cycles0;
        let short = c.short_wkc.load(Ordering::Relaxed) - short0;
        let nd = c.delta_n.load(Ordering::Relaxed).max(1);
        eprintln!(
            "soem-driver: {cycles} cycles done after SYNC0 on, {short} with working counter \
             below {expected_wkc} (last {}); PI delta (ec_DCtime - 50 us mod cycle) over the \
             second half: mean |.| {} ns, max |.| {} ns, last {} ns; wake-up late max {} us",
            c.wkc.load(Ordering::Relaxed),
            c.delta_abs_sum.load(Ordering::Relaxed) / nd,
            c.delta_abs_max.load(Ordering::Relaxed),
            c.delta.load(Ordering::Relaxed),
            c.late_max.load(Ordering::Relaxed) / 1000
        );
        Ok(())
    };
    c.stop.store(true, Ordering::Relaxed);
    thread.join().map_err(|_| "the cyclic thread panicked")?;
    unsafe { ec_close() };
    result
}
