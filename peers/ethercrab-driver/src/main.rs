//! Drives emulated (or real) slaves with the real ethercrab MainDevice, Distributed Clocks set
//! up exactly as ethercrab's own documentation of `SubDeviceGroup::configure_dc_sync` and
//! `tx_rx_dc` and its examples/dc.rs show: the example's `Timeouts` (PDU 2 s, state
//! transition 10 s, wait loop 5 ms) and `MainDeviceConfig` (10 000 static drift-compensation
//! sync iterations during init, no resend), `set_dc_sync(DcSync::Sync0)` on every SubDevice,
//! `into_pre_op_pdi`, `configure_dc_sync` (SYNC0 starts 100 ms ahead, period = cycle, process
//! data half way through the cycle), `request_into_op`, then the DC-aware cyclic call
//! `tx_rx_dc` waiting `next_cycle_wait` each cycle.
//!
//! It measures nothing itself: run it against `ecdc emulate --json`, whose yardstick reports
//! what the SYNC0 pulses did (scripts/peers-bench.sh).
//!
//! Usage: ethercrab-driver [--eeprom-timeout-ms N] IFACE [SECONDS] [CYCLE_US]
//! (defaults: 10 s, 1000 us; EEPROM timeout: the example's, i.e. ethercrab's default 10 ms)
//!
//! `--eeprom-timeout-ms` changes `Timeouts::eeprom` and nothing else. It exists because
//! ethercrab bounds each SII busy-poll loop (src/eeprom/device_provider.rs `wait_while_busy`)
//! by that timeout while sleeping the example's 5 ms `wait_loop_delay` per busy read, and on a
//! loaded host whose wake-ups come late one busy read can use up the default 10 ms; raising it
//! lets bring-up finish there without touching anything DC does. scripts/peers-bench.sh runs it
//! as a separate, labelled master (`ethercrab-eeprom100`), never in place of the example's.

#[path = "../../common/logged_main.rs"]
mod logged_main;

use std::time::{Duration, Instant};

use ethercrab::{
    std::ethercat_now,
    subdevice_group::{CycleInfo, DcConfiguration, TxRxResponse},
    DcSync, MainDevice, MainDeviceConfig, PduStorage, Timeouts,
};
use logged_main::logged_main;

// ecdc choice: room for the 32-slave tree of scripts/peers-bench.sh and its process data.
const MAX_SUBDEVICES: usize = 64;
const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
const MAX_FRAMES: usize = 32;
const PDI_LEN: usize = 512;

static PDU_STORAGE: PduStorage<MAX_FRAMES, MAX_PDU_DATA> = PduStorage::new();

const USAGE: &str = "usage: ethercrab-driver [--eeprom-timeout-ms N] IFACE [SECONDS] [CYCLE_US]";

fn arg<T: std::str::FromStr>(args: &[String], i: usize, default: T) -> Result<T, String> {
    match args.get(i) {
        None => Ok(default),
        Some(s) => s
            .parse()
            .map_err(|_| format!("argument {}: cannot parse {s:?}", i + 1)),
    }
}

/// The positional arguments and the EEPROM timeout, if `--eeprom-timeout-ms N` was given
/// (anywhere on the line).
fn parse_args() -> Result<(Vec<String>, Option<Duration>), String> {
    let mut positional = Vec::new();
    let mut eeprom = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if a == "--eeprom-timeout-ms" {
            let v = args.next().ok_or(USAGE)?;
            let ms: u64 = v
                .parse()
                .map_err(|_| format!("--eeprom-timeout-ms: cannot parse {v:?}"))?;
            eeprom = Some(Duration::from_millis(ms));
        } else if a.starts_with("--") {
            return Err(format!("unknown option {a}; {USAGE}"));
        } else {
            positional.push(a);
        }
    }
    Ok((positional, eeprom))
}

fn main() {
    logged_main("ethercrab-driver", "info", run);
}

fn run() -> Result<(), String> {
    let (args, eeprom_timeout) = parse_args()?;
    let iface: String = args.first().cloned().ok_or(USAGE)?;
    let seconds: f64 = arg(&args, 1, 10.0)?;
    let cycle_us: u64 = arg(&args, 2, 1000)?;
    let cycle_time = Duration::from_micros(cycle_us);

    let (tx, rx, pdu_loop) = PDU_STORAGE
        .try_split()
        .map_err(|_| "PDU storage already split")?;
    // Timeouts and configuration exactly as ethercrab 0.7.1's examples/dc.rs sets them: its
    // default PDU timeout (30 ms, no resend) lets one reply delayed by a loaded host end
    // bring-up with `timeout: PDU`; the example waits 2 s per PDU and 10 s per state
    // transition and leaves the retry behaviour at its default (no resend). The example leaves
    // the EEPROM timeout at ethercrab's default too, unless `--eeprom-timeout-ms` says otherwise.
    let example = Timeouts {
        wait_loop_delay: Duration::from_millis(5),
        state_transition: Duration::from_secs(10),
        pdu: Duration::from_millis(2000),
        ..Timeouts::default()
    };
    let timeouts = Timeouts {
        eeprom: eeprom_timeout.unwrap_or(example.eeprom),
        ..example
    };
    // Printed so each run's log says which EEPROM timeout it had.
    eprintln!(
        "ethercrab-driver: EEPROM timeout {} ms{}",
        timeouts.eeprom.as_millis(),
        if eeprom_timeout.is_some() {
            " (--eeprom-timeout-ms; the example keeps the default)"
        } else {
            " (the example's: ethercrab's default)"
        }
    );
    let maindevice = MainDevice::new(
        pdu_loop,
        timeouts,
        MainDeviceConfig {
            dc_static_sync_iterations: 10_000,
            ..MainDeviceConfig::default()
        },
    );
    let task =
        ethercrab::std::tx_rx_task(&iface, tx, rx).map_err(|e| format!("opening {iface}: {e}"))?;
    smol::spawn(task).detach();

    smol::block_on(async {
        let started = Instant::now();
        let mut group = maindevice
            .init_single_group::<MAX_SUBDEVICES, PDI_LEN>(ethercat_now)
            .await
            .map_err(|e| format!("init: {e}"))?;
        eprintln!(
            "ethercrab-driver: {} SubDevices after init ({} ms)",
            group.len(),
            started.elapsed().as_millis()
        );
        for mut subdevice in group.iter_mut(&maindevice) {
            // What ethercrab read from the SubDevice's SII EEPROM, for checking against the
            // emulator's own view (.ci/layers/80-peers.sh).
            let id = subdevice.identity();
            eprintln!(
                "ethercrab-driver: SubDevice {:#06x}: vendor 0x{:08x} product 0x{:08x} rev \
                 0x{:08x} serial {} name {:?}",
                subdevice.configured_address(),
                id.vendor_id,
                id.product_id,
                id.revision,
                id.serial,
                subdevice.name()
            );
            subdevice.set_dc_sync(DcSync::Sync0);
        }
        let group = group
            .into_pre_op_pdi(&maindevice)
            .await
            .map_err(|e| format!("PRE-OP -> PRE-OP with PDI: {e}"))?
            .configure_dc_sync(
                &maindevice,
                DcConfiguration {
                    start_delay: Duration::from_millis(100),
                    sync0_period: cycle_time,
                    sync0_shift: cycle_time / 2,
                },
            )
            .await
            .map_err(|e| format!("DC configuration: {e}"))?
            .request_into_op(&maindevice)
            .await
            .map_err(|e| format!("PRE-OP -> SAFE-OP -> OP: {e}"))?;

        // Until every SubDevice is in OP, sending process data so DC can start.
        let op_request = Instant::now();
        loop {
            let now = Instant::now();
            let response @ TxRxResponse {
                extra: CycleInfo {
                    next_cycle_wait, ..
                },
                ..
            } = group
                .tx_rx_dc(&maindevice)
                .await
                .map_err(|e| format!("TX/RX: {e}"))?;
            if response.all_op() {
                break;
            }
            if op_request.elapsed() > Duration::from_secs(10) {
                return Err(format!(
                    "SubDevices not in OP after 10 s: {:?}",
                    response.group_state()
                ));
            }
            smol::Timer::at(now + next_cycle_wait).await;
        }
        eprintln!(
            "ethercrab-driver: all SubDevices in OP after {} ms ({} ms since start)",
            op_request.elapsed().as_millis(),
            started.elapsed().as_millis()
        );

        // The application cycle. ethercrab's examples end the program on a TX/RX error; here a
        // failed cycle (a reply later than ethercrab's PDU timeout, which a loaded host can
        // cause) is counted and the next cycle starts one period later, so one slow reply does
        // not end the measurement. The count is printed and ends up in the results.
        let until = Instant::now() + Duration::from_secs_f64(seconds.max(0.0));
        let mut cycles = 0u64;
        let mut failed = 0u64;
        let mut last_error = None;
        while Instant::now() < until {
            let now = Instant::now();
            match group.tx_rx_dc(&maindevice).await {
                Ok(TxRxResponse {
                    extra:
                        CycleInfo {
                            next_cycle_wait, ..
                        },
                    ..
                }) => {
                    cycles += 1;
                    smol::Timer::at(now + next_cycle_wait).await;
                }
                Err(e) => {
                    failed += 1;
                    last_error = Some(e.to_string());
                    smol::Timer::at(now + cycle_time).await;
                }
            }
        }
        eprintln!(
            "ethercrab-driver: {cycles} cycles done, {failed} failed{}",
            last_error.map_or(String::new(), |e| format!(" (last: {e})"))
        );
        Ok(())
    })
}
