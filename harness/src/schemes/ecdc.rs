//! ecdc itself: the sans-IO [`Machine`] driven by the deterministic [`Sim`] driver. This file
//! only adapts it to the [`Scheme`] interface and counts the frames that carry the reference
//! time (everything sent in `DriftBurst`, `DriftCheck` and `Cyclic`).

use ecdc_core::dc::{Config, Event, Machine, MonitorConfig, State, SyncConfig, TdiffSource};

use super::{Given, Scheme, Written};
use crate::emu::{Network, TrueTime};
use crate::sim::Sim;

/// Slave capacity of the simulated machine.
pub const CAPACITY: usize = 256;

/// ecdc's machine on the emulator, with the default capacity.
pub type Ecdc = EcdcN<CAPACITY>;

/// ecdc's machine on the emulator, for up to `N` slaves.
pub struct EcdcN<const N: usize> {
    sim: Sim<N>,
    dist_frames: u64,
}

/// ecdc's default configuration for a run: SYNC0 and the monitor at `cycle_ns`, and nothing
/// told about t_Diff. `_esi_t_diff_ns` (the scenario's nominal t_P − t_F, what an ESI would
/// say) is accepted for the callers but not given to the machine: `Config::t_diff_ns` stays
/// 0 and the bring-up measures every ESC's t_Diff itself (REQ-DC-121), so no number of a
/// comparison depends on the emulator's truth. [`config_told`] is the variant that is told.
pub fn config(_esi_t_diff_ns: i32, cycle_ns: u32) -> Config {
    config_told(0, cycle_ns)
}

/// [`config`] with `t_diff_ns` given as the fallback for slaves whose t_Diff is not measured
/// (the measurement stays on).
pub fn config_told(t_diff_ns: i32, cycle_ns: u32) -> Config {
    let d = Config::default();
    Config {
        t_diff_ns,
        sync: Some(SyncConfig {
            sync0_cycle_ns: cycle_ns,
            ..SyncConfig::default()
        }),
        monitor: MonitorConfig {
            cycle_ns: u64::from(cycle_ns),
            ..d.monitor
        },
        ..d
    }
}

impl<const N: usize> EcdcN<N> {
    /// The machine with `cfg` on `net`, started at true time 0.
    pub fn new(net: Network, cfg: Config) -> anyhow::Result<Self> {
        if net.slave_count() > N {
            anyhow::bail!(
                "ecdc simulate supports up to {N} slaves, scenario has {}",
                net.slave_count()
            );
        }
        let mut sim =
            Sim::<N>::configured(cfg, net).map_err(|e| anyhow::anyhow!("ecdc config: {e:?}"))?;
        sim.start();
        Ok(EcdcN {
            sim,
            dist_frames: 0,
        })
    }

    /// The machine's events so far (true time, event).
    pub fn events(&self) -> &[(TrueTime, Event)] {
        self.sim.events()
    }

    /// The machine.
    pub fn machine(&self) -> &Machine<N> {
        &self.sim.machine
    }

    /// Per slave (position order) the t_Diff the last bring-up used, ns, and where it came
    /// from (measured, same ESC type, configured, fallback, default), for reports.
    pub fn t_diff(&self) -> Vec<(i32, TdiffSource)> {
        self.sim
            .machine
            .slaves()
            .iter()
            .map(|s| (s.t_diff_ns, s.t_diff_source))
            .collect()
    }
}

pub use crate::emu::yardstick::max_anchor;

impl<const N: usize> Scheme for EcdcN<N> {
    fn t_diff_used(&self) -> Option<Vec<(i64, String)>> {
        Some(
            self.t_diff()
                .into_iter()
                .map(|(v, src)| {
                    // Reports number slaves from 1; the machine's positions start at 0.
                    let text = match src {
                        TdiffSource::SameType { from } => {
                            format!("same ESC type as slave {}", u32::from(from) + 1)
                        }
                        other => other.to_string(),
                    };
                    (i64::from(v), text)
                })
                .collect(),
        )
    }

    fn name(&self) -> &'static str {
        "ecdc"
    }

    fn advance(&mut self, until: TrueTime) -> anyhow::Result<()> {
        // Step until `until`, and further while a frame in flight has already been evaluated
        // past the driver's time at some slave (the emulator evaluates each ESC lazily up to
        // its last visit): the recorder samples the clocks at or after those instants, and the
        // driver must not send a frame before them afterwards.
        let mut extra = 0u32;
        loop {
            if self.sim.now() >= until {
                let ahead = max_anchor(&self.sim.net) > self.sim.now();
                if !ahead || extra >= 100_000 {
                    break;
                }
                extra += 1;
            }
            let st = self.sim.machine.state();
            let sent = self.sim.stats().sent;
            let more = self.sim.step().map_err(|e| anyhow::anyhow!("sim: {e}"))?;
            if matches!(st, State::DriftBurst | State::DriftCheck | State::Cyclic) {
                self.dist_frames += self.sim.stats().sent - sent;
            }
            if !more {
                break;
            }
        }
        if until > self.sim.net.now() {
            self.sim.net.advance_to(until)?;
        }
        Ok(())
    }

    fn net(&mut self) -> &mut Network {
        &mut self.sim.net
    }

    fn reference(&self) -> usize {
        usize::from(self.sim.machine.reference().unwrap_or(0))
    }

    fn dist_frames(&self) -> u64 {
        self.dist_frames
    }

    fn static_drift_frames(&self) -> Option<u64> {
        self.sim.events().iter().find_map(|(_, e)| match e {
            Event::DriftConverged { frames, .. } => Some(u64::from(*frames)),
            _ => None,
        })
    }

    fn written(&self) -> Vec<Written> {
        self.sim
            .machine
            .slaves()
            .iter()
            .map(|s| Written {
                offset: s.offset_written.then_some(s.offset as i64),
                delay: s.dc.has_system_time().then_some(s.delay_ns),
            })
            .collect()
    }

    fn frames_lost(&self) -> u64 {
        self.sim.stats().lost
    }

    fn given(&self) -> Given {
        // Whatever t_DIFF the configuration carries was handed in, not measured.
        let t = self.sim.machine.config().t_diff_ns;
        let mut g = Given::new();
        if t != 0 {
            g.insert("t_diff_ns", i64::from(t));
        }
        g
    }
}
