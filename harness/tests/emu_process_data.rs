//! AL state machine with SyncManager and FMMU checks and process data through LRW/LRD/LWR
//! (REQ-ESC-020, REQ-ESC-025..REQ-ESC-028): invalid transitions, error flag and code,
//! acknowledge, PREOP→SAFEOP refused without a valid SyncManager configuration or without
//! FMMUs mapping it, working counters per command and outputs reaching the device only in OP.
//!
//! verifies: REQ-ESC-020, REQ-ESC-025, REQ-ESC-026, REQ-ESC-027, REQ-ESC-028

mod emu_support;

use ecdc_core::wire::{Address, Command};
use ecdc_harness::emu::{Device, Network, Scenario, SlaveSpec};
use emu_support::*;

fn net_of(devices: &[Device], mailbox: bool) -> (Network, u64) {
    let mut sc = Scenario::default().ideal();
    sc.defaults.mailbox = mailbox;
    for d in devices {
        sc = sc.with_slave(SlaveSpec {
            device: Some(*d),
            ..SlaveSpec::default()
        });
    }
    addressed(&sc)
}

fn fpwr(net: &mut Network, t: &mut u64, st: u16, ado: u16, d: &[u8]) -> u16 {
    let (r, a) = fpwr_at(net, *t, st, ado, d);
    *t = a + 1_000;
    r.wkc
}

fn fprd(net: &mut Network, t: &mut u64, st: u16, ado: u16, len: usize) -> Vec<u8> {
    let (r, a) = fprd_at(net, *t, st, ado, len);
    *t = a + 1_000;
    r.data
}

/// Requests `state` and returns (AL status, AL status code).
fn request(net: &mut Network, t: &mut u64, st: u16, state: u16) -> (u16, u16) {
    assert_eq!(fpwr(net, t, st, 0x0120, &state.to_le_bytes()), 1);
    let r = fprd(net, t, st, 0x0130, 6);
    (u16_of(&r), u16_of(&r[4..]))
}

/// SyncManager `n` = (start, length, control, activate).
fn sm(net: &mut Network, t: &mut u64, st: u16, n: u16, start: u16, len: u16, ctrl: u8) {
    let mut d = start.to_le_bytes().to_vec();
    d.extend_from_slice(&len.to_le_bytes());
    d.extend_from_slice(&[ctrl, 0, 1, 0]);
    assert_eq!(fpwr(net, t, st, 0x0800 + 8 * n, &d), 1);
}

/// One FMMU entry: logical start, length, physical start, type (1 read, 2 write).
struct Map {
    log: u32,
    len: u16,
    phys: u16,
    typ: u8,
}

/// Writes FMMU `n` (all bits of each byte, enabled).
fn fmmu(net: &mut Network, t: &mut u64, st: u16, n: u16, m: Map) {
    let mut d = m.log.to_le_bytes().to_vec();
    d.extend_from_slice(&m.len.to_le_bytes());
    d.extend_from_slice(&[0, 7]);
    d.extend_from_slice(&m.phys.to_le_bytes());
    d.extend_from_slice(&[0, m.typ, 1, 0, 0, 0]);
    assert_eq!(fpwr(net, t, st, 0x0600 + 16 * n, &d), 1);
}

/// REQ-ESC-020: invalid transitions set the error flag and 0x0011; with the flag set a
/// higher state waits for the acknowledge while a lower one is still taken.
// verifies: REQ-ESC-020
#[test]
fn invalid_transitions_and_acknowledge() {
    let (mut net, mut t) = net_of(&[Device::Bare], false);
    // (AL control written, (AL status, AL status code) read back, what it shows)
    for (control, want, what) in [
        (4, (0x11, 0x0011), "INIT -> SAFEOP"),
        (2, (0x11, 0x0011), "PREOP waits for the acknowledge"),
        (0x12, (0x02, 0), "ack + PREOP"),
        (8, (0x12, 0x0011), "PREOP -> OP"),
        (1, (0x11, 0x0011), "a lower state is taken, the error stays"),
        (0x11, (0x01, 0), "ack + INIT"),
        (0x0F, (0x11, 0x0012), "no such state"),
    ] {
        assert_eq!(request(&mut net, &mut t, 0x1000, control), want, "{what}");
    }
    // A slave without process data reaches OP with no SyncManager configured.
    request(&mut net, &mut t, 0x1000, 0x11);
    for s in [2u16, 4, 8] {
        assert_eq!(request(&mut net, &mut t, 0x1000, s), (s, 0));
    }
    assert_eq!(net.al_state(0), Some(8));
}

/// REQ-ESC-025: PREOP→SAFEOP needs the process-data SyncManagers as the SII describes them
/// (0x001D outputs, 0x001E inputs); INIT→PREOP needs the mailbox ones when there is a
/// mailbox (0x0016).
// verifies: REQ-ESC-025
#[test]
fn safeop_refused_without_a_valid_sm_configuration() {
    let (mut net, mut t) = net_of(&[Device::Io8], false);
    let st = 0x1000;
    assert_eq!(request(&mut net, &mut t, st, 2), (0x02, 0));
    assert_eq!(
        request(&mut net, &mut t, st, 4),
        (0x12, 0x001D),
        "no SM at all"
    );
    // (SyncManager, start, length, control byte) written, then ack + SAFEOP refused with
    for ((n, start, len, ctrl), code, what) in [
        (
            (0, 0x1100, 2, 0x64),
            0x001D,
            "outputs with the wrong length",
        ),
        (
            (0, 0x1100, 1, 0x20),
            0x001D,
            "outputs with the wrong direction",
        ),
        (
            (0, 0x1100, 1, 0x64),
            0x001E,
            "outputs right, inputs missing",
        ),
        ((1, 0x0F00, 1, 0x20), 0x001E, "inputs outside process RAM"),
    ] {
        sm(&mut net, &mut t, st, n, start, len, ctrl);
        assert_eq!(request(&mut net, &mut t, st, 0x14), (0x12, code), "{what}");
    }
    // Another place in process RAM is fine: the master chooses the buffer addresses.
    sm(&mut net, &mut t, st, 1, 0x1400, 1, 0x20);
    map_both(&mut net, &mut t, st, (0x1100, 1), (0x1400, 1));
    assert_eq!(request(&mut net, &mut t, st, 0x14), (0x04, 0));
    assert_eq!(request(&mut net, &mut t, st, 8), (0x08, 0));

    let (mut net, mut t) = net_of(&[Device::Servo], true);
    assert_eq!(
        request(&mut net, &mut t, st, 2),
        (0x11, 0x0016),
        "mailbox SMs missing"
    );
    sm(&mut net, &mut t, st, 0, 0x1000, 128, 0x26);
    sm(&mut net, &mut t, st, 1, 0x1080, 128, 0x22);
    assert_eq!(request(&mut net, &mut t, st, 0x12), (0x02, 0));
    // With a mailbox the process data SMs are 2 and 3.
    sm(&mut net, &mut t, st, 2, 0x1100, 6, 0x64);
    assert_eq!(request(&mut net, &mut t, st, 4), (0x12, 0x001E));
    sm(&mut net, &mut t, st, 3, 0x1180, 6, 0x20);
    map_both(&mut net, &mut t, st, (0x1100, 6), (0x1180, 6));
    assert_eq!(request(&mut net, &mut t, st, 0x14), (0x04, 0));
}

/// FMMU 0 writes logical 0.. into the outputs buffer, FMMU 1 reads the inputs buffer into
/// logical 16.. (each given as physical start and length).
fn map_both(net: &mut Network, t: &mut u64, st: u16, out: (u16, u16), inp: (u16, u16)) {
    map_at(net, t, st, (0, out.0, out.1), (16, inp.0, inp.1));
}

/// FMMU 0 writes the outputs buffer, FMMU 1 reads the inputs buffer, each given as
/// (logical start, physical start, length).
fn map_at(net: &mut Network, t: &mut u64, st: u16, out: (u32, u16, u16), inp: (u32, u16, u16)) {
    let m = |(log, phys, len), typ| Map {
        log,
        len,
        phys,
        typ,
    };
    fmmu(net, t, st, 0, m(out, 2));
    fmmu(net, t, st, 1, m(inp, 1));
}

/// REQ-ESC-028: with both process-data SyncManagers right, PREOP→SAFEOP still needs an
/// activated FMMU of each one's direction over its buffer (0x001D outputs, 0x001E inputs);
/// the refusal sets the error flag, a higher request waits for the acknowledge, and a
/// read/write FMMU serves both directions.
// verifies: REQ-ESC-028
#[test]
fn safeop_refused_without_fmmus() {
    let (mut net, mut t) = net_of(&[Device::Io8], false);
    let st = 0x1000;
    let m = |log, phys, typ| Map {
        log,
        len: 1,
        phys,
        typ,
    };
    assert_eq!(request(&mut net, &mut t, st, 2), (0x02, 0));
    sm(&mut net, &mut t, st, 0, 0x1100, 1, 0x64);
    sm(&mut net, &mut t, st, 1, 0x1180, 1, 0x20);
    assert_eq!(
        request(&mut net, &mut t, st, 4),
        (0x12, 0x001D),
        "SyncManagers right, no FMMU"
    );
    assert_eq!(net.al_state(0), Some(0x02), "the state stays PREOP");
    // Outputs mapped by a read FMMU: wrong direction.
    fmmu(&mut net, &mut t, st, 0, m(0, 0x1100, 1));
    assert_eq!(request(&mut net, &mut t, st, 0x14), (0x12, 0x001D));
    // A write FMMU beside the buffer, not over it.
    fmmu(&mut net, &mut t, st, 0, m(0, 0x1101, 2));
    assert_eq!(request(&mut net, &mut t, st, 0x14), (0x12, 0x001D));
    // Outputs mapped; inputs not.
    fmmu(&mut net, &mut t, st, 0, m(0, 0x1100, 2));
    assert_eq!(
        request(&mut net, &mut t, st, 0x14),
        (0x12, 0x001E),
        "outputs mapped, inputs not"
    );
    // An inputs FMMU that is written but not activated.
    fmmu(&mut net, &mut t, st, 1, m(16, 0x1180, 1));
    assert_eq!(fpwr(&mut net, &mut t, st, 0x0600 + 16 + 12, &[0]), 1);
    assert_eq!(request(&mut net, &mut t, st, 0x14), (0x12, 0x001E));
    // The same entry in FMMU 9, beyond the 8 this ESC has.
    fmmu(&mut net, &mut t, st, 9, m(16, 0x1180, 1));
    assert_eq!(request(&mut net, &mut t, st, 0x14), (0x12, 0x001E));
    // Activated in FMMU 1: the configuration is now right, but SAFEOP waits for the
    // acknowledge.
    assert_eq!(fpwr(&mut net, &mut t, st, 0x0600 + 16 + 12, &[1]), 1);
    assert_eq!(
        request(&mut net, &mut t, st, 4),
        (0x12, 0x001E),
        "no acknowledge"
    );
    assert_eq!(request(&mut net, &mut t, st, 0x14), (0x04, 0));
    assert_eq!(request(&mut net, &mut t, st, 8), (0x08, 0));

    // One read/write FMMU over both buffers (0x1100..0x1180 and 0x1180) serves both.
    let (mut net, mut t) = net_of(&[Device::Io8], false);
    request(&mut net, &mut t, st, 2);
    sm(&mut net, &mut t, st, 0, 0x1100, 1, 0x64);
    sm(&mut net, &mut t, st, 1, 0x1180, 1, 0x20);
    fmmu(
        &mut net,
        &mut t,
        st,
        0,
        Map {
            log: 0,
            len: 0x81,
            phys: 0x1100,
            typ: 3,
        },
    );
    assert_eq!(request(&mut net, &mut t, st, 4), (0x04, 0));
}

/// Configures an io8 (slave 0) and a servo (slave 1) the way a master does from their SII:
/// outputs of both at logical 0..7, inputs at logical 16..23 (io8 at 16, servo at 17..22).
fn configure(net: &mut Network, t: &mut u64) {
    // (station, logical output start, logical input start, buffer length)
    for (st, log_out, log_in, len) in [(0x1000, 0, 16, 1), (0x1001, 1, 17, 6)] {
        sm(net, t, st, 0, 0x1100, len, 0x64);
        sm(net, t, st, 1, 0x1180, len, 0x20);
        map_at(net, t, st, (log_out, 0x1100, len), (log_in, 0x1180, len));
    }
}

fn logical(net: &mut Network, t: &mut u64, c: Command, data: &[u8]) -> (Vec<u8>, u16) {
    let (r, a) = one(net, *t, c, Address::logical(0), data);
    *t = a + 1_000;
    (r.data, r.wkc)
}

/// REQ-ESC-026/027: no process data before SAFEOP; in SAFEOP and OP the working counter
/// follows LRW +1 read +2 write per slave, LRD +1, LWR +1; outputs reach the device only in
/// OP, and its inputs come back.
// verifies: REQ-ESC-026
#[test]
fn process_data_working_counters_and_outputs() {
    let (mut net, mut t) = net_of(&[Device::Io8, Device::Servo], false);
    configure(&mut net, &mut t);
    let mut out = vec![0u8; 24];
    out[0] = 0xA5;
    out[1..3].copy_from_slice(&0x000Fu16.to_le_bytes());
    out[3..7].copy_from_slice(&123_456i32.to_le_bytes());
    for st in [0x1000u16, 0x1001] {
        request(&mut net, &mut t, st, 2);
    }
    // PREOP: the firmware keeps the process-data SMs deactivated: nothing counts.
    assert_eq!(logical(&mut net, &mut t, Command::Lrw, &out).1, 0);
    assert_eq!(logical(&mut net, &mut t, Command::Lrd, &out).1, 0);
    for st in [0x1000u16, 0x1001] {
        assert_eq!(request(&mut net, &mut t, st, 4), (4, 0));
    }
    // SAFEOP: data flows, outputs stay in the safe state.
    assert_eq!(logical(&mut net, &mut t, Command::Lrw, &out).1, 6);
    assert_eq!(logical(&mut net, &mut t, Command::Lrd, &out).1, 2);
    assert_eq!(logical(&mut net, &mut t, Command::Lwr, &out).1, 2);
    net.advance_to(t).unwrap();
    assert_eq!(net.process_image(0).unwrap().outputs, [0]);
    assert_eq!(net.process_image(1).unwrap().outputs, [0; 6]);
    for st in [0x1000u16, 0x1001] {
        assert_eq!(request(&mut net, &mut t, st, 8), (8, 0));
    }
    // OP: outputs reach the device; the next frame reads its inputs.
    assert_eq!(logical(&mut net, &mut t, Command::Lwr, &out).1, 2);
    net.advance_to(t).unwrap();
    let io = net.process_image(0).unwrap();
    assert_eq!((io.al_state, io.outputs.clone()), (8, vec![0xA5]));
    assert_eq!(net.process_image(1).unwrap().outputs, out[1..7]);
    let (data, wkc) = logical(&mut net, &mut t, Command::Lrw, &out);
    assert_eq!(wkc, 6);
    assert_eq!(data[16], 0xA5, "io8 inputs wired to its outputs");
    assert_eq!(
        u16_of(&data[17..]),
        0x000F,
        "servo status echoes the control word"
    );
    assert_eq!(
        u32_of(&data[19..]) as i32,
        123_456,
        "actual position follows"
    );
    assert_eq!(data[..7], out[..7], "LRW reads back the written outputs");
    // LRD: reads only (the written bytes are not applied).
    let mut other = out.clone();
    other[0] = 0x00;
    assert_eq!(logical(&mut net, &mut t, Command::Lrd, &other).1, 2);
    net.advance_to(t).unwrap();
    assert_eq!(net.process_image(0).unwrap().outputs, [0xA5]);
    // An LRW covering only the outputs counts +2 per slave.
    assert_eq!(logical(&mut net, &mut t, Command::Lrw, &other[..8]).1, 4);
    // Only the io8's inputs: +1.
    assert_eq!(logical_at(&mut net, &mut t, 16, 1), 1);
    // ECAT cannot write into an input buffer: an FPWR there does not count.
    assert_eq!(fpwr(&mut net, &mut t, 0x1000, 0x1180, &[0xFF]), 0);
    // Back to SAFEOP: outputs return to the safe state.
    request(&mut net, &mut t, 0x1000, 4);
    logical(&mut net, &mut t, Command::Lwr, &out);
    net.advance_to(t).unwrap();
    assert_eq!(net.process_image(0).unwrap().outputs, [0]);
}

fn logical_at(net: &mut Network, t: &mut u64, at: u32, len: usize) -> u16 {
    let (r, a) = one(net, *t, Command::Lrw, Address::logical(at), &vec![0; len]);
    *t = a + 1_000;
    r.wkc
}

/// REQ-ESC-025 for an image file: the checks follow the file's SyncManager category, including
/// a buffer in register space where the SII puts it (as digital-output terminals do at
/// 0x0F00).
// verifies: REQ-ESC-025
#[test]
fn checks_follow_an_image_file() {
    let (net, _) = net_of(&[Device::Io8], false);
    let mut b = net.sii_image(0).unwrap().to_bytes();
    // Walk the categories (written here) to the SyncManager one and move SM0 to 0x0F00.
    let mut i = 0x80;
    loop {
        let typ = u16_of(&b[i..]);
        let len = 2 * usize::from(u16_of(&b[i + 2..]));
        assert_ne!(typ, 0xFFFF, "no SyncManager category");
        if typ == 41 {
            b[i + 4..i + 6].copy_from_slice(&0x0F00u16.to_le_bytes());
            break;
        }
        i += 4 + len;
    }
    let dir = std::env::temp_dir().join(format!("ecdc-emu-pd-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("io8_0f00.bin");
    std::fs::write(&path, &b).unwrap();
    let sc = Scenario::default().ideal().with_slave(SlaveSpec {
        sii_file: Some(path),
        ..SlaveSpec::default()
    });
    let (mut net, mut t) = addressed(&sc);
    let st = 0x1000;
    request(&mut net, &mut t, st, 2);
    sm(&mut net, &mut t, st, 1, 0x1180, 1, 0x20);
    // Register space other than where the file puts the buffer: refused.
    sm(&mut net, &mut t, st, 0, 0x0E00, 1, 0x64);
    assert_eq!(request(&mut net, &mut t, st, 4), (0x12, 0x001D));
    sm(&mut net, &mut t, st, 0, 0x0F00, 1, 0x64);
    map_both(&mut net, &mut t, st, (0x0F00, 1), (0x1180, 1));
    assert_eq!(request(&mut net, &mut t, st, 0x14), (0x04, 0));
}
