//! Command-line options shared by the subcommands that open an interface
//! (`emulate`, `scan`, `run`, `rtt`): the socket and the real-time setup.

use crate::runtime::errors::RuntimeError;
use crate::runtime::rt::{self, RtOptions, RtState};
use crate::runtime::socket::{RawSocket, SocketOptions, WaitMode};

/// Which interface and how to use it.
#[derive(Debug, Clone, clap::Args)]
pub struct LinkArgs {
    /// Network interface connected to the first slave's port 0 (e.g. eth1, or a veth end).
    #[arg(long, short = 'i', value_parser = super::validate::iface_name)]
    pub iface: String,
    /// Bypass the qdisc on transmit (PACKET_QDISC_BYPASS). Faster path, but tcpdump/tshark on
    /// this interface no longer sees our TX frames: capture on the peer or use --pcap.
    #[arg(long)]
    pub qdisc_bypass: bool,
    /// How to wait for replies: poll (sleep in ppoll) or spin (busy-wait; use with --rt).
    #[arg(long, value_enum, default_value_t = WaitMode::Poll)]
    pub wait: WaitMode,
    /// Do not bring the interface up if it is down (fail instead).
    #[arg(long)]
    pub no_bring_up: bool,
}

impl LinkArgs {
    /// Opens the raw socket; prints the interface's warnings to stderr. `need_carrier`:
    /// fail if the link stays down (a master), or accept it with a warning (a server).
    pub fn open(&self, min_payload: u32, need_carrier: bool) -> Result<RawSocket, RuntimeError> {
        let defaults = SocketOptions::default();
        let opts = SocketOptions {
            carrier_wait: if need_carrier {
                defaults.carrier_wait
            } else {
                None
            },
            qdisc_bypass: self.qdisc_bypass,
            bring_up: !self.no_bring_up,
            wait: self.wait,
            min_payload,
            ..defaults
        };
        let sock = RawSocket::open(&self.iface, &opts)?;
        for w in &sock.info().warnings {
            eprintln!("warning: {w}");
        }
        Ok(sock)
    }
}

/// The interface and real-time options of the subcommands that run a cyclic loop on a link
/// (`emulate`, `run`, `rtt`).
#[derive(Debug, Clone, clap::Args)]
pub struct RtLinkArgs {
    #[command(flatten)]
    pub link: LinkArgs,
    #[command(flatten)]
    pub rt: RtArgs,
}

/// Real-time options.
#[derive(Debug, Clone, clap::Args)]
pub struct RtArgs {
    /// Real-time mode: SCHED_FIFO, mlockall, /dev/cpu_dma_latency held at 0, CPU pinning.
    /// Each step degrades to a warning when not permitted.
    #[arg(long)]
    pub rt: bool,
    /// SCHED_FIFO priority for --rt (leave headroom above for IRQ threads).
    #[arg(long, default_value_t = 80, allow_negative_numbers = true,
          value_parser = clap::value_parser!(i32).range(1..=99))]
    pub priority: i32,
    /// CPU to pin to with --rt (default: the last CPU); must be online.
    #[arg(long, allow_negative_numbers = true, value_parser = super::validate::usize_in(0, libc::CPU_SETSIZE as usize - 1))]
    pub cpu: Option<usize>,
}

impl RtArgs {
    /// Applies the options to the calling thread (always reduces timer slack); prints warnings.
    pub fn apply(&self) -> RtState {
        let opts = if self.rt {
            RtOptions::full(self.priority, self.cpu)
        } else {
            RtOptions::default()
        };
        let st = rt::apply(&opts);
        if self.rt {
            for w in &st.warnings {
                eprintln!("warning: {w}");
            }
        }
        st
    }
}
