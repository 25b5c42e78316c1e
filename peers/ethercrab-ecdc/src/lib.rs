//! One TX/RX loop for two masters on one wire: the real ethercrab `MainDevice` (discovery,
//! station addresses, AL states, process data) and ecdc-core's sans-IO DC machine (delays,
//! offsets, static and cyclic drift compensation, SYNC0) on the stations ethercrab assigned.
//!
//! ethercrab lets the application drive its frames: [`PduTx::next_sendable_frame`] hands out
//! each frame it queued and [`PduRx::receive_frame`] takes every received one. [`TxRx`] does
//! that and, on the same link, sends the frames of [`Machine::poll_transmit`] and hands their
//! replies to [`Machine::handle_frame`].
//!
//! **Routing.** ethercrab numbers its datagrams with a free-running `u8` counter over all 256
//! values, so a datagram index range cannot be kept for ecdc (ecdc's `index_first..+count`
//! would collide with ethercrab's indices every 256 datagrams), and ethercrab looks up a reply
//! by its first datagram's index alone. ecdc's frames therefore go out as frames of their own
//! with a source MAC of their own, [`ECDC_MAC`], and every received frame is routed by its
//! source MAC ([`route`]). An ESC changes only bit 0x02 of the first source byte on the way
//! (the "processed" mark, docs/background/wire-format.md §1.4), so the rest of the address
//! survives the ring. Inside its frames ecdc still uses its default index
//! range 0x80..=0xFF and matches replies by index, command, register, station and length.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use ecdc_core::dc::{Config, Event, Machine, State, Stations, TdiffSource};
use ecdc_core::time::SystemTime;
use ecdc_harness::runtime::clock::{self, DcClock};
use ecdc_harness::runtime::socket::Link;
use ethercrab::{std::ethercat_now, MainDevice, MainDeviceConfig, PduLoop, PduRx, PduTx, Timeouts};

/// SubDevices one group can hold, and ecdc's slave capacity. ecdc choice: 16, as the
/// ethercrab-only driver, above the benchmark's 6.
pub const MAX_SUBDEVICES: usize = 16;
/// Process image bytes of the group. ecdc choice: 64, as the ethercrab-only driver.
pub const PDI_LEN: usize = 64;

/// EtherType of EtherCAT frames (docs/background/wire-format.md §1.1).
pub const ETHERTYPE_ECAT: u16 = 0x88A4;

/// Source MAC of ecdc's frames. ecdc choice: ethercrab's fixed source address
/// 10:10:10:10:10:10 with the last two bytes replaced by EC:DC: locally administered
/// and unicast like ethercrab's (bits 0x02 and 0x01 of the first byte clear, so the ESC's
/// processed mark stays distinguishable), and different from it in bytes the ESCs never touch.
pub const ECDC_MAC: [u8; 6] = [0x10, 0x10, 0x10, 0x10, 0xEC, 0xDC];

/// Longest the loop waits for a frame before looking for new ethercrab frames to send, ns.
/// ethercrab's futures queue a frame and wake a waker; this loop does not block on that
/// waker (it waits in the socket's `ppoll`), so a frame ethercrab queued waits at most this
/// long. ecdc choice: 200 us, 20 % of the 1 ms cycle: the wait delays only ethercrab's
/// process data, while every wake-up competes for the CPU with the DC replies. On the shared
/// 2-core host at load 4.5, one 10 s run each: 50 us gave 269 lost DC cycles and 11
/// re-initialisations, 200 us 103 and 2.
pub const MAX_WAIT_NS: u64 = 200_000;

/// Who a received frame belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Route {
    /// ecdc's DC machine (source MAC [`ECDC_MAC`], processed or not).
    Ecdc,
    /// ethercrab (every other EtherCAT frame; it drops its own unprocessed echo itself).
    Ethercrab,
    /// Not an EtherCAT frame.
    Other,
}

/// Routes a received Ethernet frame by its EtherType and source MAC.
pub fn route(frame: &[u8]) -> Route {
    let (Some(src), Some(et)) = (frame.get(6..12), frame.get(12..14)) else {
        return Route::Other;
    };
    if u16::from_be_bytes([et[0], et[1]]) != ETHERTYPE_ECAT {
        return Route::Other;
    }
    let first_unmarked = src[0] & !0x02;
    if first_unmarked == ECDC_MAC[0] && src[1..] == ECDC_MAC[1..] {
        Route::Ecdc
    } else {
        Route::Ethercrab
    }
}

/// Writes [`ECDC_MAC`] as the source of an Ethernet frame the machine built.
pub fn mark_ecdc(frame: &mut [u8]) {
    if let Some(src) = frame.get_mut(6..12) {
        src.copy_from_slice(&ECDC_MAC);
    }
}

/// What the loop reports to the application thread.
#[derive(Debug, Clone, Default)]
pub struct Status {
    /// The machine's state.
    pub state: Option<State>,
    /// `Event::SyncStarted` seen since the last bring-up start.
    pub sync_started: bool,
    /// The machine is locked now.
    pub locked: bool,
    /// Monotonic ns when lock was first reached.
    pub first_lock_mono_ns: Option<u64>,
    /// Every event of the machine, as text, with its monotonic time.
    pub events: Vec<(u64, String)>,
    /// Faults among them.
    pub faults: u32,
    /// Restarts among them.
    pub restarts: u32,
    /// Station address of each slave the machine brought up.
    pub stations: Vec<u16>,
    /// Frame counters of the loop.
    pub counters: Counters,
    /// The machine's own counters (lost cycles, timeouts, frames).
    pub machine: ecdc_core::dc::Stats,
    /// Longest time between two turns of the loop, ns (a stall of the loop thread).
    pub max_turn_gap_ns: u64,
}

/// Frames the loop moved.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counters {
    /// ethercrab frames sent.
    pub crab_sent: u64,
    /// Frames handed to ethercrab.
    pub crab_received: u64,
    /// Frames ethercrab refused (`receive_frame` error: no frame waiting for that index).
    pub crab_refused: u64,
    /// ecdc frames sent.
    pub ecdc_sent: u64,
    /// Frames handed to the machine.
    pub ecdc_received: u64,
    /// Non-EtherCAT frames dropped.
    pub other: u64,
    /// Send errors (either master).
    pub send_errors: u64,
}

/// Control and status shared between the loop thread and the application.
#[derive(Debug, Default)]
pub struct Shared {
    /// Set by the application: start ecdc's bring-up (after ethercrab's init).
    pub start_dc: AtomicBool,
    /// Set by the application: leave the loop.
    pub stop: AtomicBool,
    /// The loop's report, refreshed after every event and every 100 ms.
    pub status: Mutex<Status>,
}

impl Shared {
    /// A copy of the current status.
    pub fn snapshot(&self) -> Status {
        self.status.lock().map(|s| s.clone()).unwrap_or_default()
    }
}

/// The TX/RX loop: ethercrab's PDU frames and ecdc's DC frames over one link.
pub struct TxRx<'sto, L: Link, const N: usize> {
    link: L,
    tx: PduTx<'sto>,
    rx: PduRx<'sto>,
    machine: Box<Machine<N>>,
    clock: DcClock,
    shared: Arc<Shared>,
    counters: Counters,
    /// Slave count of the bring-up whose t_Diff values are pinned, if any.
    pinned: Option<u16>,
    max_turn_gap_ns: u64,
}

impl<'sto, L: Link, const N: usize> TxRx<'sto, L, N> {
    /// A loop over `link`; the machine starts when `shared.start_dc` is set.
    pub fn new(
        link: L,
        tx: PduTx<'sto>,
        rx: PduRx<'sto>,
        machine: Box<Machine<N>>,
        clock: DcClock,
        shared: Arc<Shared>,
    ) -> Self {
        TxRx {
            link,
            tx,
            rx,
            machine,
            clock,
            shared,
            counters: Counters::default(),
            pinned: None,
            max_turn_gap_ns: 0,
        }
    }

    /// Runs until `shared.stop` or ethercrab's exit request; returns the link and the machine.
    pub fn run(mut self) -> (L, Box<Machine<N>>) {
        let mut frame = [0u8; 1514];
        // Longer than any frame, so a truncated one is seen as such.
        let mut rxbuf = [0u8; 2048];
        let mut dc_running = false;
        let mut last_report = 0u64;
        let mut last_turn: Option<u64> = None;
        loop {
            let turn = clock::now_ns();
            if let Some(prev) = last_turn {
                // A turn waits at most MAX_WAIT_NS or the machine's deadline; more is a stall.
                let gap = turn.saturating_sub(prev);
                if dc_running {
                    self.max_turn_gap_ns = self.max_turn_gap_ns.max(gap);
                }
            }
            last_turn = Some(turn);
            if self.shared.stop.load(Ordering::Acquire) || self.tx.should_exit() {
                break;
            }
            if !dc_running && self.shared.start_dc.load(Ordering::Acquire) {
                self.machine.start(SystemTime(self.clock.now()));
                dc_running = true;
            }
            // ethercrab's queued frames, as its own `tx_rx_task` sends them.
            while let Some(f) = self.tx.next_sendable_frame() {
                let link = &mut self.link;
                let sent = f.send_blocking(|data| {
                    link.send(data)
                        .map(|()| data.len())
                        .map_err(|_| ethercrab::error::Error::SendFrame)
                });
                match sent {
                    Ok(_) => self.counters.crab_sent += 1,
                    Err(_) => self.counters.send_errors += 1,
                }
            }
            if dc_running {
                while let Some(n) = self
                    .machine
                    .poll_transmit(SystemTime(self.clock.now()), &mut frame)
                {
                    let f = &mut frame[..n];
                    mark_ecdc(f);
                    match self.link.send(f) {
                        Ok(()) => self.counters.ecdc_sent += 1,
                        Err(_) => self.counters.send_errors += 1,
                    }
                }
            }
            let now = clock::now_ns();
            let mut deadline = now.saturating_add(MAX_WAIT_NS);
            if dc_running {
                if let Some(t) = self.machine.poll_timeout() {
                    deadline = deadline.min(self.clock.to_mono(t.as_nanos()));
                }
            }
            match self.link.recv(&mut rxbuf, deadline) {
                Ok(Some(n)) if n <= rxbuf.len() => {
                    let received = &rxbuf[..n];
                    match route(received) {
                        Route::Ecdc if dc_running => {
                            let at = self.link.last_rx_time().unwrap_or_else(clock::now_ns);
                            self.machine
                                .handle_frame(SystemTime(self.clock.at(at)), received);
                            self.counters.ecdc_received += 1;
                        }
                        Route::Ecdc => self.counters.other += 1,
                        Route::Ethercrab => match self.rx.receive_frame(received) {
                            Ok(_) => self.counters.crab_received += 1,
                            Err(_) => self.counters.crab_refused += 1,
                        },
                        Route::Other => self.counters.other += 1,
                    }
                }
                Ok(_) => {}
                Err(_) => self.counters.other += 1,
            }
            if dc_running {
                self.machine.handle_timeout(SystemTime(self.clock.now()));
            }
            let mono = clock::now_ns();
            let mut fresh = false;
            let mut events = Vec::new();
            while let Some(e) = self.machine.poll_event() {
                events.push(e);
                fresh = true;
            }
            self.pin_t_diff(&events);
            if fresh || mono.saturating_sub(last_report) > 100_000_000 {
                last_report = mono;
                self.report(mono, &events);
            }
        }
        let mono = clock::now_ns();
        self.report(mono, &[]);
        (self.link, self.machine)
    }

    /// After the first lock, pins every slave's measured t_Diff as its configured value, so a
    /// later bring-up uses it. ethercrab keeps the slaves in OP, where the machine does not
    /// close ports to measure t_Diff (REQ-DC-123), and a re-initialisation after a fault (a
    /// host stall long enough to lose `max_lost_cycles` cycles) would otherwise fall back to
    /// `Config::t_diff_ns` and write delays off by t_Diff/2 per hop (seed 000 eq. 13) while
    /// it keeps the offsets (REQ-DC-030). A bring-up that finds a different number of slaves
    /// unpins them: positions no longer name the same ESCs.
    fn pin_t_diff(&mut self, events: &[Event]) {
        for e in events {
            match *e {
                Event::SlavesFound { count, .. } if self.pinned.is_some_and(|c| c != count) => {
                    for pos in 0..count.max(self.pinned.unwrap_or(0)) {
                        let _ = self.machine.set_slave_t_diff(pos, None);
                    }
                    self.pinned = None;
                }
                Event::Locked { .. } if self.pinned.is_none() => {
                    let values: Vec<(u16, i32, TdiffSource)> = (0u16..)
                        .zip(self.machine.slaves())
                        .map(|(pos, s)| (pos, s.t_diff_ns, s.t_diff_source))
                        .collect();
                    for (pos, v, src) in &values {
                        if matches!(src, TdiffSource::Measured | TdiffSource::SameType { .. }) {
                            let _ = self.machine.set_slave_t_diff(*pos, Some(*v));
                        }
                    }
                    self.pinned = u16::try_from(values.len()).ok();
                }
                _ => {}
            }
        }
    }

    fn report(&self, mono: u64, events: &[Event]) {
        let Ok(mut s) = self.shared.status.lock() else {
            return;
        };
        for e in events {
            match e {
                Event::SyncStarted { .. } => s.sync_started = true,
                Event::Error(_) => s.faults += 1,
                Event::Restarting => {
                    s.restarts += 1;
                    s.sync_started = false;
                }
                _ => {}
            }
            s.events.push((mono, format!("{e:?}")));
        }
        s.locked = self.machine.is_locked();
        if s.locked && s.first_lock_mono_ns.is_none() {
            s.first_lock_mono_ns = Some(mono);
        }
        s.state = Some(self.machine.state());
        s.stations = self.machine.slaves().iter().map(|x| x.station).collect();
        s.counters = self.counters;
        s.machine = *self.machine.stats();
        s.max_turn_gap_ns = self.max_turn_gap_ns;
    }
}

/// What to run.
#[derive(Debug, Clone)]
pub struct Options {
    /// Seconds of cyclic process data once every SubDevice is in OP.
    pub seconds: f64,
    /// Cycle of the process data and of ecdc's DC datagrams, us.
    pub cycle_us: u64,
    /// Longest wait for ecdc's lock after ethercrab's init, and for OP.
    pub timeout: Duration,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            seconds: 10.0,
            cycle_us: 1000,
            timeout: Duration::from_secs(10),
        }
    }
}

/// What a run did.
#[derive(Debug, Clone)]
pub struct Report {
    /// SubDevices ethercrab found.
    pub subdevices: usize,
    /// ethercrab's init (discovery, addresses, SII, PRE-OP), ms.
    pub init_ms: f64,
    /// From the start of ecdc's bring-up to its lock, ms.
    pub dc_lock_ms: f64,
    /// From the OP request to every SubDevice in OP, ms.
    pub op_ms: f64,
    /// Monotonic ns when every SubDevice was in OP (the clock of [`Status::events`]).
    pub op_mono_ns: u64,
    /// Process-data cycles in OP.
    pub cycles: u64,
    /// Cycles whose LRW working counter differed from the first cycle's in OP.
    pub wkc_changes: u64,
    /// The loop's final status (ecdc's events, stations, frame counters).
    pub status: Status,
}

/// The ecdc machine's configuration in this embedding: `ecdc run`'s defaults (the cycle as
/// SYNC0 period and cyclic cadence), with the station addresses adopted from ethercrab
/// (REQ-DC-140) instead of assigned.
pub fn dc_config(cycle_ns: u64) -> Result<Config, String> {
    let mut cfg = Config {
        stations: Stations::Adopt,
        ..Config::default()
    };
    cfg.monitor.cycle_ns = cycle_ns;
    let mut s = cfg.sync.unwrap_or_default();
    s.sync0_cycle_ns = u32::try_from(cycle_ns).map_err(|_| "cycle too long".to_string())?;
    cfg.sync = Some(s);
    Ok(cfg)
}

/// The whole master: ethercrab's init to PRE-OP, ecdc's DC bring-up to lock, ethercrab's
/// PRE-OP → SAFE-OP → OP and `opts.seconds` of process data, all frames through one [`TxRx`]
/// loop on its own thread. ethercrab's DC is off: no static sync iterations, no
/// `configure_dc_sync`, no `tx_rx_dc` (its init still measures delays and writes offsets in
/// INIT/PRE-OP, which ecdc's bring-up then measures and writes again).
pub fn run<L: Link + Send>(
    link: L,
    tx: PduTx<'static>,
    rx: PduRx<'static>,
    pdu_loop: PduLoop<'static>,
    opts: &Options,
) -> Result<(Report, L), String> {
    let cycle = Duration::from_micros(opts.cycle_us);
    let cfg = dc_config(opts.cycle_us.saturating_mul(1000))?;
    let machine: Box<Machine<MAX_SUBDEVICES>> =
        Box::new(Machine::new(cfg).map_err(|e| format!("DC configuration: {e:?}"))?);
    let maindevice = MainDevice::new(
        pdu_loop,
        Timeouts::default(),
        MainDeviceConfig {
            dc_static_sync_iterations: 0,
            ..MainDeviceConfig::default()
        },
    );
    let shared = Arc::new(Shared::default());
    std::thread::scope(|sc| {
        let loop_shared = Arc::clone(&shared);
        let handle = sc.spawn(move || {
            TxRx::new(link, tx, rx, machine, DcClock::from_realtime(), loop_shared).run()
        });
        let result = smol::block_on(application(&maindevice, &shared, cycle, opts));
        shared.stop.store(true, Ordering::Release);
        let (link, _machine) = handle
            .join()
            .map_err(|_| "the TX/RX loop panicked".to_string())?;
        result.map(|mut r| {
            r.status = shared.snapshot();
            (r, link)
        })
    })
}

async fn application(
    maindevice: &MainDevice<'_>,
    shared: &Shared,
    cycle: Duration,
    opts: &Options,
) -> Result<Report, String> {
    let started = Instant::now();
    let group = maindevice
        .init_single_group::<MAX_SUBDEVICES, PDI_LEN>(ethercat_now)
        .await
        .map_err(|e| format!("ethercrab init: {e}"))?;
    let init_ms = started.elapsed().as_secs_f64() * 1e3;

    // ecdc's bring-up while every SubDevice is in PRE-OP and ethercrab sends nothing: the
    // machine steps 0x0920 only before SYNC0 starts, and no slave is in SAFE-OP yet.
    shared.start_dc.store(true, Ordering::Release);
    let dc_started = Instant::now();
    loop {
        let s = shared.snapshot();
        if s.locked {
            break;
        }
        if dc_started.elapsed() > opts.timeout {
            let tail: Vec<&str> = s.events.iter().rev().take(5).map(|(_, e)| &e[..]).collect();
            return Err(format!(
                "ecdc not locked after {:?} (state {:?}, last events {tail:?})",
                opts.timeout, s.state
            ));
        }
        smol::Timer::after(Duration::from_millis(5)).await;
    }
    let dc_lock_ms = dc_started.elapsed().as_secs_f64() * 1e3;

    let group = group
        .into_pre_op_pdi(maindevice)
        .await
        .map_err(|e| format!("PRE-OP -> PRE-OP with PDI: {e}"))?
        .request_into_op(maindevice)
        .await
        .map_err(|e| format!("PRE-OP -> SAFE-OP -> OP: {e}"))?;
    let op_request = Instant::now();
    let mut next = Instant::now();
    loop {
        let response = group
            .tx_rx(maindevice)
            .await
            .map_err(|e| format!("TX/RX: {e}"))?;
        if response.all_op() {
            break;
        }
        if op_request.elapsed() > opts.timeout {
            return Err(format!(
                "SubDevices not in OP after {:?}: {:?}",
                opts.timeout,
                response.group_state()
            ));
        }
        next += cycle;
        smol::Timer::at(next).await;
    }
    let op_ms = op_request.elapsed().as_secs_f64() * 1e3;
    let op_mono_ns = clock::now_ns();

    let until = Instant::now() + Duration::from_secs_f64(opts.seconds.max(0.0));
    let mut cycles = 0u64;
    let mut wkc_first = None;
    let mut wkc_changes = 0u64;
    next = Instant::now();
    while Instant::now() < until {
        let response = group
            .tx_rx(maindevice)
            .await
            .map_err(|e| format!("TX/RX: {e}"))?;
        cycles += 1;
        if *wkc_first.get_or_insert(response.working_counter) != response.working_counter {
            wkc_changes += 1;
        }
        next += cycle;
        // Behind by more than a cycle (a stall of the host): restart the grid, do not burst.
        let now = Instant::now();
        if next + cycle < now {
            next = now;
        }
        smol::Timer::at(next).await;
    }
    Ok(Report {
        subdevices: group.len(),
        init_ms,
        dc_lock_ms,
        op_ms,
        op_mono_ns,
        cycles,
        wkc_changes,
        status: Status::default(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(src: [u8; 6], ethertype: u16) -> Vec<u8> {
        let mut f = vec![0u8; 60];
        f[..6].fill(0xFF);
        f[6..12].copy_from_slice(&src);
        f[12..14].copy_from_slice(&ethertype.to_be_bytes());
        f
    }

    #[test]
    fn routes_by_source_mac_processed_or_not() {
        let crab = [0x10; 6];
        let crab_processed = [0x12, 0x10, 0x10, 0x10, 0x10, 0x10];
        let mut ecdc_processed = ECDC_MAC;
        ecdc_processed[0] |= 0x02;
        assert_eq!(route(&frame(ECDC_MAC, 0x88A4)), Route::Ecdc);
        assert_eq!(route(&frame(ecdc_processed, 0x88A4)), Route::Ecdc);
        assert_eq!(route(&frame(crab, 0x88A4)), Route::Ethercrab);
        assert_eq!(route(&frame(crab_processed, 0x88A4)), Route::Ethercrab);
        assert_eq!(route(&frame(ECDC_MAC, 0x0800)), Route::Other);
        assert_eq!(route(&[0u8; 13]), Route::Other);
    }

    #[test]
    fn marks_the_frames_the_machine_built() {
        let mut f = frame([0x10; 6], 0x88A4);
        mark_ecdc(&mut f);
        assert_eq!(&f[6..12], &ECDC_MAC);
        assert_eq!(route(&f), Route::Ecdc);
        assert_eq!(ECDC_MAC[0] & 0x03, 0, "unicast, processed bit clear");
    }
}
