//! The scenario files scripts/peers-bench.sh runs the other masters on: they load, validate,
//! have the slaves they say, and differ from the scenarios they are named after only in the
//! device behind each ESC (process data, so SOEM has a frame for its DC time datagram).

use ecdc_harness::emu::scenario::{ResolvedSlave, SiiSource};
use ecdc_harness::emu::{Device, Scenario};

fn load(name: &str) -> Scenario {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios")
        .join(name);
    let sc = Scenario::load(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
    sc.validate(None).unwrap_or_else(|e| panic!("{name}: {e}"));
    sc
}

/// The resolved slaves with the device and the EEPROM content (which follows from the device)
/// blanked, and the devices seen.
fn dc_part(sc: &Scenario) -> (Vec<ResolvedSlave>, Vec<Device>) {
    let mut slaves = sc.resolve().unwrap();
    let devices = slaves.iter().map(|s| s.device).collect();
    for s in &mut slaves {
        s.device = Device::Bare;
        s.sii = SiiSource::File(std::path::PathBuf::new());
    }
    (slaves, devices)
}

#[test]
fn seed000_line6_is_seed000_line_with_io8_devices() {
    let file = load("peers_seed000_line6.toml");
    let (slaves, devices) = dc_part(&file);
    let (want, _) = dc_part(&Scenario::seed000_line());
    assert_eq!(slaves, want);
    assert_eq!(devices, vec![Device::Io8; 6]);
    assert_eq!(file.seed, Scenario::seed000_line().seed);
    assert_eq!(file.timing, Scenario::seed000_line().timing);
}

#[test]
fn seed003_is_bench_seed003_with_servo_devices() {
    let file = load("peers_seed003.toml");
    let bench = load("bench_seed003.toml");
    let (slaves, devices) = dc_part(&file);
    assert_eq!(slaves, dc_part(&bench).0);
    assert_eq!(devices, vec![Device::Servo; 2]);
    assert_eq!(file.seed, bench.seed);
    assert_eq!(file.timing, bench.timing);
}

#[test]
fn tree32_has_the_shape_its_comment_gives() {
    let (slaves, devices) = dc_part(&load("peers_tree32.toml"));
    assert_eq!(slaves.len(), 32);
    assert_eq!(devices, vec![Device::Io8; 32]);
    let parent = |i: usize| slaves[i].parent;
    assert_eq!(slaves[0].ports, 4);
    assert_eq!(parent(0), None);
    assert_eq!(parent(1), Some((0, 3)));
    assert_eq!(parent(5), Some((0, 1)));
    assert_eq!(parent(12), Some((0, 2)));
    assert_eq!(slaves[12].ports, 3);
    assert_eq!(parent(13), Some((12, 1)));
    assert_eq!(parent(21), Some((12, 2)));
    for i in (2..=4).chain(6..=11).chain(14..=20).chain(22..=31) {
        assert_eq!(parent(i), Some((i - 1, 1)), "slave {i} continues its line");
    }
}
