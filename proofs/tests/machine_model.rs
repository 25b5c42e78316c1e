//! Model-based test (proptest-state-machine) of the DC machine against the reference model of
//! its observable contract, `ecdc_spec::machine_model` (REQ-DC-110, REQ-DC-111, REQ-DC-113, P6).
//!
//! Requirements checked here: the bring-up order and its requests — discovery (REQ-DC-100),
//! latch, offsets only to writable slaves (REQ-DC-030), loop reset 0x0934 before 0x0930
//! (REQ-DC-031), drift gate before any SYNC write (REQ-DC-033, REQ-DC-104), 0x0981 cleared
//! before 0x0990/0x09A0/0x09A4 and 0x0980 last (REQ-DC-034), 0x0982 never written
//! (REQ-DC-035), one start for all from one reference read (REQ-DC-036), cyclic requests and
//! lost cycles coasted up to the limit (REQ-DC-106); stale replies and junk change nothing
//! (REQ-DC-032).
//!
//! Random sequences of abstract inputs (complete exchange, stale reply then exchange, lost
//! frame, junk, `reset`, `start`) run on the reference model and on the real machine driven
//! against the emulated line of `ecdc_proofs::model::World` (which also checks the P6 frame and
//! index-matching properties on every step). After every input the machine's state, its lock
//! and the kinds of the events it emitted must equal the model's, and every datagram it sent
//! must be one the model allows in the state it was sent in.
//!
//! verifies: P6, REQ-DC-030, REQ-DC-031, REQ-DC-032, REQ-DC-033, REQ-DC-034, REQ-DC-035, REQ-DC-036, REQ-DC-100, REQ-DC-104, REQ-DC-106, REQ-DC-110, REQ-DC-111, REQ-DC-113

use ecdc_core::dc::{Error, Event, State};
use ecdc_core::wire::EthernetFrame;
use ecdc_proofs::machine::script_config;
use ecdc_proofs::model::{Action, World};
use ecdc_spec::machine_model::{allowed_request, EventKind, Input, ModelConfig, RefMachine};
use proptest::prelude::*;
use proptest_state_machine::{prop_state_machine, ReferenceStateMachine, StateMachineTest};

/// Reference state: the model, the line it describes, the events of the last input.
#[derive(Debug, Clone)]
struct Ref {
    m: RefMachine,
    al: [u16; 4],
    events: Vec<EventKind>,
}

struct RefSm;

fn model_config() -> ModelConfig {
    let c = script_config();
    ModelConfig {
        latch_rounds: c.latch_rounds,
        retries: c.retries,
        max_lost_cycles: c.monitor.max_lost_cycles,
    }
}

impl ReferenceStateMachine for RefSm {
    type State = Ref;
    type Transition = Input;

    fn init_state() -> BoxedStrategy<Ref> {
        let al = prop_oneof![Just(0x01u16), Just(0x02), Just(0x04), Just(0x08)];
        (1u16..=4, proptest::array::uniform4(al))
            .prop_map(|(k, al)| {
                let writable = al
                    .iter()
                    .take(usize::from(k))
                    .filter(|a| matches!(**a, 0x01 | 0x02))
                    .count() as u16;
                let mut m = RefMachine::new(model_config(), k, writable);
                m.apply(Input::Start);
                Ref {
                    m,
                    al,
                    events: Vec::new(),
                }
            })
            .boxed()
    }

    fn transitions(r: &Ref) -> BoxedStrategy<Input> {
        // Mostly exchanges, so sequences reach `Cyclic`; from `Idle` mostly `start`.
        let start = if r.m.state == State::Idle { 8 } else { 1 };
        prop_oneof![
            16 => Just(Input::Exchange),
            2 => Just(Input::StaleThenExchange),
            3 => Just(Input::Lost),
            1 => Just(Input::Junk),
            1 => Just(Input::Reset),
            start => Just(Input::Start),
        ]
        .boxed()
    }

    fn apply(mut s: Ref, t: &Input) -> Ref {
        s.events = s.m.apply(*t);
        s
    }
}

struct MachineTest;

fn step(w: &mut World, a: Action, events: &mut Vec<Event>, sent: &mut Vec<(State, Vec<u8>)>) {
    if let Err(v) = w.step(a) {
        panic!("P6 violated by {a:?}: {v:?}");
    }
    events.extend_from_slice(w.last_events());
    sent.extend(w.last_tx().cloned());
}

/// Transmits the machine's next frame, advancing the clock to its deadlines while it has
/// nothing to send; false if it sends nothing (idle).
fn transmit(w: &mut World, events: &mut Vec<Event>, sent: &mut Vec<(State, Vec<u8>)>) -> bool {
    for _ in 0..50 {
        let n = sent.len();
        step(w, Action::Tx, events, sent);
        if sent.len() > n {
            return true;
        }
        if w.machine().poll_timeout().is_none() {
            return false;
        }
        step(w, Action::ToDeadline, events, sent);
    }
    false
}

fn kind(e: &Event) -> Option<EventKind> {
    Some(match *e {
        Event::SlavesFound { count, dc } => EventKind::SlavesFound(count, dc),
        Event::TdiffResolved { .. } => EventKind::TdiffResolved,
        Event::DelaysMeasured { .. } => EventKind::DelaysMeasured,
        Event::OffsetsWritten {
            written,
            skipped_running,
        } => EventKind::OffsetsWritten(written, skipped_running),
        Event::DriftConverged { .. } => EventKind::DriftConverged,
        Event::SyncStarted { slaves, .. } => EventKind::SyncStarted(slaves),
        Event::Locked { .. } => EventKind::Locked,
        Event::Error(Error::Timeout { state }) => EventKind::Timeout(state),
        Event::Restarting => EventKind::Restarting,
        Event::HoldoverStarted { .. } => EventKind::HoldoverStarted,
        Event::HoldoverEnded { .. } => EventKind::HoldoverEnded,
        _ => return None,
    })
}

impl StateMachineTest for MachineTest {
    type SystemUnderTest = World;
    type Reference = RefSm;

    fn init_test(r: &Ref) -> World {
        World::new(r.m.k, r.al)
            .expect("valid config")
            .without_clocks()
    }

    fn apply(mut w: World, r: &Ref, t: Input) -> World {
        let mut events = Vec::new();
        let mut sent = Vec::new();
        match t {
            Input::Reset => step(&mut w, Action::Reset, &mut events, &mut sent),
            Input::Start => step(&mut w, Action::Start, &mut events, &mut sent),
            Input::Junk => step(&mut w, Action::Junk, &mut events, &mut sent),
            Input::Exchange | Input::StaleThenExchange => {
                if transmit(&mut w, &mut events, &mut sent) {
                    if t == Input::StaleThenExchange {
                        step(&mut w, Action::DeliverOlder, &mut events, &mut sent);
                    }
                    step(&mut w, Action::DeliverNewest, &mut events, &mut sent);
                }
            }
            Input::Lost => {
                if transmit(&mut w, &mut events, &mut sent) {
                    step(&mut w, Action::Lose, &mut events, &mut sent);
                    step(&mut w, Action::ToDeadline, &mut events, &mut sent);
                }
            }
        }
        let kinds: Vec<Option<EventKind>> = events.iter().map(kind).collect();
        let expected: Vec<Option<EventKind>> = r.events.iter().copied().map(Some).collect();
        assert_eq!(kinds, expected, "events after {t:?} (all: {events:?})");
        assert_eq!(w.machine().state(), r.m.state, "state after {t:?}");
        assert_eq!(w.machine().is_locked(), r.m.locked(), "lock after {t:?}");
        for (state, frame) in &sent {
            let eth = EthernetFrame::new_checked(&frame[..]).expect("machine frame parses");
            let ecat = eth.ecat_frame().expect("EtherCAT frame");
            // REQ-DC-031: per station, 0x0934 (filter depth) before 0x0930 (speed counter start).
            let mut depth_written: Vec<u16> = Vec::new();
            // REQ-DC-036: one start time for all, from one reference read.
            let mut starts: Vec<Vec<u8>> = Vec::new();
            let mut datagrams = 0;
            for d in ecat.iter() {
                let d = d.expect("datagram");
                datagrams += 1;
                let cmd = d.command().expect("command");
                match d.ado() {
                    0x0934 => depth_written.push(d.adp()),
                    0x0930 => assert!(
                        depth_written.contains(&d.adp()),
                        "0x0930 before 0x0934 at station {:#06x}",
                        d.adp()
                    ),
                    0x0990 => starts.push(d.data().to_vec()),
                    _ => {}
                }
                assert!(
                    allowed_request(*state, cmd, d.ado(), d.data_len()),
                    "{cmd:?} 0x{:04X} ({} bytes) sent in {state:?}",
                    d.ado(),
                    d.data_len()
                );
            }
            assert!(
                starts.windows(2).all(|w| w[0] == w[1]),
                "SYNC starts differ"
            );
            if *state == State::ReadReferenceTime {
                assert_eq!(
                    datagrams, 1,
                    "one reference read, no per-slave 0x0910 reads"
                );
            }
        }
        w
    }
}

prop_state_machine! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]
    /// The machine follows the reference model on random input sequences.
    #[test]
    fn machine_follows_reference_model(sequential 1..120 => MachineTest);
}

/// Not vacuous: a fault-free sequence drives model and machine through the whole bring-up to a
/// locked `Cyclic`, with every event of the contract.
#[test]
fn reference_model_full_bringup() {
    let mut r = <RefSm as ReferenceStateMachine>::init_state()
        .new_tree(&mut proptest::test_runner::TestRunner::deterministic())
        .expect("tree")
        .current();
    r.m = RefMachine::new(model_config(), 3, 3);
    r.al = [1, 1, 1, 1];
    r.m.apply(Input::Start);
    let mut w = MachineTest::init_test(&r);
    let mut all = Vec::new();
    for _ in 0..40 {
        r = RefSm::apply(r, &Input::Exchange);
        all.extend(r.events.iter().copied());
        w = MachineTest::apply(w, &r, Input::Exchange);
    }
    assert!(w.machine().is_locked());
    assert!(all.contains(&EventKind::OffsetsWritten(3, 0)));
    assert!(all.contains(&EventKind::SyncStarted(3)));
}
