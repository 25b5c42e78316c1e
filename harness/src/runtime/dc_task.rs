//! The cyclic task of `ecdc run`: each cycle the DC machine appends its FRMW (reference time
//! distribution) and 0x092C monitoring datagrams to the frame, the reply feeds the machine,
//! and the master-follows-reference servo turns (app time − reference time) into a correction
//! of the next wake-up deadline.
//!
//! App time: the master's nominal DC time of each cycle, advancing exactly one period per
//! cycle (docs/background/servo-design.md §3: the IgH/SOEM model). It is what the FRMW carries and what the machine
//! gets as `now`; the servo moves the *wake-ups* so that app time and the reference clock agree,
//! and absorbs large offsets by whole periods (`app_time_step_ns`). A cycle that woke more than
//! P/4 late is given to the servo as a missing sample (holdover): it measures an OS stall, not
//! the clocks. Other samples are corrected by the measured delay from the deadline to the
//! `send` call, so the servo sees the timer's phase rather than each cycle's wake-up jitter.

use ecdc_core::dc::{Event, Machine, State};
use ecdc_core::servo::master::{MasterInput, MasterServo};
use ecdc_core::time::SystemTime;
use ecdc_core::wire::{EthernetFrame, FrameBuilder};

use super::clock::DcClock;
use super::cyclic::{CycleReport, CycleTask};
use super::transport::Reply;

/// Drives a [`Machine`] in `Cyclic` from the runtime's fixed-period loop.
pub struct DcTask<'a, const N: usize, F: FnMut(u64, &Event)> {
    machine: &'a mut Machine<N>,
    servo: MasterServo,
    dc: DcClock,
    period: u64,
    app_base: Option<u64>,
    app_now: u64,
    woke: u64,
    deadline: u64,
    late: bool,
    last_ref: Option<u64>,
    on_event: F,
}

impl<'a, const N: usize, F: FnMut(u64, &Event)> DcTask<'a, N, F> {
    /// A task for `machine` (already in `Cyclic`) with period `period_ns`.
    pub fn new(
        machine: &'a mut Machine<N>,
        servo: MasterServo,
        dc: DcClock,
        period_ns: u64,
        on_event: F,
    ) -> Self {
        let last_ref = machine.reference_time().map(|t| t.0);
        DcTask {
            machine,
            servo,
            dc,
            period: period_ns,
            app_base: None,
            app_now: 0,
            woke: 0,
            deadline: 0,
            late: false,
            last_ref,
            on_event,
        }
    }

    /// The servo (for the summary).
    pub fn servo(&self) -> &MasterServo {
        &self.servo
    }

    fn drain_events(&mut self, cycle: u64) {
        while let Some(e) = self.machine.poll_event() {
            (self.on_event)(cycle, &e);
        }
    }

    /// Expected working counters of the first two cyclic datagrams: FRMW (slaves with a
    /// system time) and BRD 0x092C (all slaves).
    fn expected_wkc(&self) -> (u16, u16) {
        let s = self.machine.slaves();
        let sys = s.iter().filter(|x| x.dc.has_system_time()).count();
        (
            u16::try_from(sys).unwrap_or(u16::MAX),
            u16::try_from(s.len()).unwrap_or(u16::MAX),
        )
    }
}

/// Working counters of the first two datagrams of a reply.
fn first_two_wkc(frame: &[u8]) -> Option<(u16, Option<u16>)> {
    let eth = EthernetFrame::new_checked(frame).ok()?;
    let ecat = eth.ecat_frame().ok()?;
    let mut it = ecat.iter();
    let a = it.next()?.ok()?.wkc();
    let b = it.next().and_then(|d| d.ok()).map(|d| d.wkc());
    Some((a, b))
}

impl<const N: usize, F: FnMut(u64, &Event)> CycleTask for DcTask<'_, N, F> {
    fn build(&mut self, period: u64, deadline: u64, now: u64, buf: &mut [u8]) -> Option<usize> {
        let base = *self.app_base.get_or_insert(self.dc.at(deadline));
        self.app_now = base.wrapping_add(period.wrapping_mul(self.period));
        self.woke = now;
        self.deadline = deadline;
        // A wake-up this late measures an OS stall, not the clocks: keep it out of the servo.
        self.late = now.saturating_sub(deadline) > self.period / 4;
        let mut b = FrameBuilder::new(buf).ok()?;
        if !self
            .machine
            .poll_transmit_into(SystemTime(self.app_now), &mut b)
        {
            return None;
        }
        b.finish().ok()
    }

    fn complete(&mut self, period: u64, reply: Option<(&[u8], &Reply)>) -> CycleReport {
        // A lost frame is counted as lost by the loop, not as a WKC error.
        let mut wkc_error = false;
        if let Some((bytes, _)) = reply {
            self.machine.handle_frame(SystemTime(self.app_now), bytes);
            let (sys, all) = self.expected_wkc();
            wkc_error = first_two_wkc(bytes) != Some((sys, Some(all)));
        }
        let reference = self.machine.reference_time().map(|t| t.0);
        let input = match reference {
            Some(r) if !self.late && Some(r) != self.last_ref => match reply {
                // The frame left `sent_at - deadline` after the nominal instant; the reference
                // stamped it that much later. Adding the measured delay to the app time makes
                // the sample measure the timer's phase, not this cycle's OS jitter (which no
                // correction of future deadlines could remove).
                Some((_, rep)) => MasterInput::Sample {
                    local_ns: self.woke,
                    app_ns: self
                        .app_now
                        .wrapping_add(rep.sent_at.saturating_sub(self.deadline)),
                    ref_ns: r,
                },
                None => MasterInput::Lost,
            },
            _ => MasterInput::Lost,
        };
        self.last_ref = reference;
        let out = self.servo.update(input);
        if let Some(base) = self.app_base.as_mut() {
            *base = base.wrapping_add_signed(out.app_time_step_ns);
        }
        self.drain_events(period);
        CycleReport {
            adjust_ns: out.deadline_correction_ns,
            wkc_error,
            max_092c_ns: self.machine.diff_bound_ns().map(u64::from),
            servo_error_ns: matches!(input, MasterInput::Sample { .. })
                .then_some(out.phase_error_ns),
            locked: Some(self.machine.is_locked()),
            servo_locked: Some(self.servo.is_locked()),
            stop: self.machine.state() != State::Cyclic,
        }
    }
}
