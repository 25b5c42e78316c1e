//! The `AF_PACKET` raw socket bound to EtherType 0x88A4 on one interface, and the [`Link`]
//! trait the transport uses so tests can swap in an in-memory link.
//!
//! WHY these choices (docs/background/linux-runtime.md §2):
//! - bound to 0x88A4, not `ETH_P_ALL`: the socket never sees its own transmissions;
//! - non-blocking socket plus `ppoll` with a nanosecond deadline (or a spin): `SO_RCVTIMEO`
//!   is rounded up to a kernel tick (SOEM issue #451: 1 us became 4 ms);
//! - `PACKET_QDISC_BYPASS` is optional because it hides our TX frames from local captures;
//! - promiscuous mode as a socket membership, which the kernel undoes when the socket closes.

use std::io;
use std::os::fd::{AsRawFd, OwnedFd};
use std::time::Duration;

use super::clock;
use super::errors::RuntimeError;
use super::sys;

/// The EtherCAT EtherType.
pub const ETHERTYPE_ECAT: u16 = 0x88A4;

/// Ethernet payload bytes needed for the largest EtherCAT frame (header + datagrams).
pub const FULL_PAYLOAD: u32 = 1498;

/// A frame link: the transport's only view of the network.
pub trait Link {
    /// Sends one complete Ethernet frame.
    fn send(&mut self, frame: &[u8]) -> io::Result<()>;
    /// Receives one frame into `buf`, waiting until the absolute monotonic time `deadline_ns`
    /// at most. `Ok(None)` means the deadline passed with nothing received. A frame longer than
    /// `buf` is reported with its true length (`> buf.len()`), its tail cut off.
    fn recv(&mut self, buf: &mut [u8], deadline_ns: u64) -> io::Result<Option<usize>>;

    /// Kernel receive time of the frame the last `recv` returned, as `CLOCK_MONOTONIC` ns,
    /// if the link records one (the raw socket with `SO_TIMESTAMPNS`). It excludes the time the
    /// process took to be scheduled and read the frame.
    fn last_rx_time(&self) -> Option<u64> {
        None
    }
}

/// How to wait for a reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
pub enum WaitMode {
    /// Sleep in `ppoll` until a frame arrives or the deadline passes (one wake-up per reply).
    Poll,
    /// Spin on non-blocking `recv` (a few us faster; only sensible with `--rt` on a spare CPU,
    /// under SCHED_OTHER preemption gives millisecond tails).
    Spin,
}

/// Options for [`RawSocket::open`].
#[derive(Debug, Clone)]
pub struct SocketOptions {
    /// Skip the qdisc on transmit (`PACKET_QDISC_BYPASS`). Hides TX frames from tcpdump on
    /// this interface; capture on the peer or use `--pcap` instead.
    pub qdisc_bypass: bool,
    /// Receive frames whatever their destination MAC (needed by `emulate`, harmless otherwise).
    pub promiscuous: bool,
    /// Try to bring the interface up if it is down (needs CAP_NET_ADMIN).
    pub bring_up: bool,
    /// Ethernet payload bytes the MTU must allow.
    pub min_payload: u32,
    /// How long to wait for carrier; `None` accepts an interface without carrier (with a
    /// warning), which suits a server such as `ecdc emulate` that waits for its peer anyway.
    pub carrier_wait: Option<Duration>,
    /// How [`Link::recv`] waits.
    pub wait: WaitMode,
}

impl Default for SocketOptions {
    fn default() -> Self {
        SocketOptions {
            qdisc_bypass: false,
            promiscuous: true,
            bring_up: true,
            min_payload: FULL_PAYLOAD,
            carrier_wait: Some(Duration::from_secs(5)),
            wait: WaitMode::Poll,
        }
    }
}

/// Facts about the opened interface, for logs and summaries.
#[derive(Debug, Clone, serde::Serialize)]
pub struct InterfaceInfo {
    /// Interface name.
    pub name: String,
    /// Kernel interface index.
    pub index: u32,
    /// MTU.
    pub mtu: u32,
    /// The interface's own MAC (not used as source address; see the wire codec's master MAC).
    pub mac: [u8; 6],
    /// We raised the interface ourselves.
    pub brought_up: bool,
    /// `PACKET_QDISC_BYPASS` is active.
    pub qdisc_bypass: bool,
    /// The promiscuous membership was granted.
    pub promiscuous: bool,
    /// Warnings worth printing (e.g. a degraded option).
    pub warnings: Vec<String>,
}

/// An `AF_PACKET`/`SOCK_RAW` socket bound to 0x88A4 on one interface.
#[derive(Debug)]
pub struct RawSocket {
    fd: OwnedFd,
    info: InterfaceInfo,
    wait: WaitMode,
    stamped: bool,
    last_rx: Option<u64>,
}

const IFF_UP: u32 = libc::IFF_UP as u32;
const IFF_RUNNING: u32 = libc::IFF_RUNNING as u32;

/// Interfaces listed in `/sys/class/net`, sorted (for "did you mean" messages).
pub fn list_interfaces() -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir("/sys/class/net")
        .map(|rd| {
            rd.filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    names.sort();
    names
}

impl RawSocket {
    /// Opens the socket and puts the interface into a usable state, or explains why not.
    pub fn open(name: &str, opts: &SocketOptions) -> Result<Self, RuntimeError> {
        if name.is_empty()
            || name.len() > sys::IFNAME_MAX
            || name.contains('\0')
            || name.contains('/')
        {
            return Err(RuntimeError::InvalidInterfaceName {
                name: name.to_owned(),
            });
        }
        let index = match sys::if_index(name) {
            Ok(i) => i,
            Err(e) if e.raw_os_error() == Some(libc::ENODEV) => {
                return Err(RuntimeError::NoSuchInterface {
                    name: name.to_owned(),
                    available: list_interfaces(),
                })
            }
            Err(e) => return Err(RuntimeError::os("looking up interface", name, e)),
        };
        let fd = sys::packet_socket(ETHERTYPE_ECAT)
            .map_err(|e| RuntimeError::os("opening AF_PACKET raw socket", name, e))?;
        let mut warnings = Vec::new();

        let (hw_type, mac) = sys::if_hwaddr(&fd, name)
            .map_err(|e| RuntimeError::os("reading hardware address", name, e))?;
        if hw_type != libc::ARPHRD_ETHER {
            return Err(RuntimeError::NotEthernet {
                name: name.to_owned(),
                hw_type,
            });
        }

        let mut flags = sys::if_flags(&fd, name)
            .map_err(|e| RuntimeError::os("reading interface flags", name, e))?;
        let mut brought_up = false;
        if flags & IFF_UP == 0 {
            if !opts.bring_up {
                return Err(RuntimeError::InterfaceDown {
                    name: name.to_owned(),
                    cause: io::Error::other("not raised: --no-bring-up given"),
                });
            }
            sys::set_if_flags(&fd, name, flags | IFF_UP).map_err(|cause| {
                RuntimeError::InterfaceDown {
                    name: name.to_owned(),
                    cause,
                }
            })?;
            brought_up = true;
            warnings.push(format!("interface {name} was down; brought it up"));
        }
        // Carrier: a veth is RUNNING as soon as both ends are up; a NIC needs autonegotiation.
        let wait = opts.carrier_wait.unwrap_or_default();
        let carrier_deadline =
            clock::now_ns().saturating_add(u64::try_from(wait.as_nanos()).unwrap_or(u64::MAX));
        loop {
            flags = sys::if_flags(&fd, name)
                .map_err(|e| RuntimeError::os("reading interface flags", name, e))?;
            if flags & IFF_RUNNING != 0 {
                break;
            }
            if clock::now_ns() >= carrier_deadline {
                if opts.carrier_wait.is_none() {
                    warnings.push(format!(
                        "interface {name} has no carrier yet; waiting for the peer"
                    ));
                    break;
                }
                return Err(RuntimeError::NoCarrier {
                    name: name.to_owned(),
                });
            }
            std::thread::sleep(Duration::from_millis(20));
        }

        let mtu = sys::if_mtu(&fd, name).map_err(|e| RuntimeError::os("reading MTU", name, e))?;
        if mtu < opts.min_payload {
            return Err(RuntimeError::MtuTooSmall {
                name: name.to_owned(),
                mtu,
                need: opts.min_payload,
            });
        }

        sys::bind_packet(&fd, index, ETHERTYPE_ECAT)
            .map_err(|e| RuntimeError::os("binding raw socket", name, e))?;

        let mut qdisc_bypass = false;
        if opts.qdisc_bypass {
            match sys::set_int_option(&fd, libc::SOL_PACKET, libc::PACKET_QDISC_BYPASS, 1) {
                Ok(()) => qdisc_bypass = true,
                Err(e) => warnings.push(format!(
                    "PACKET_QDISC_BYPASS refused ({e}); using the qdisc"
                )),
            }
        }
        let mut promiscuous = false;
        if opts.promiscuous {
            match sys::add_promisc_membership(&fd, index) {
                Ok(()) => promiscuous = true,
                Err(e) => warnings.push(format!(
                    "promiscuous membership refused ({e}); only broadcast frames"
                )),
            }
        }
        // Kernel receive stamps: cheap, and they let `emulate` use the frame's arrival time
        // rather than the time the process got round to reading it.
        let stamped = match sys::enable_rx_timestamps(&fd) {
            Ok(()) => true,
            Err(e) => {
                warnings.push(format!(
                    "SO_TIMESTAMPNS refused ({e}); using user-space receive times"
                ));
                false
            }
        };
        // Throw away anything queued between socket() and bind() (frames from any interface).
        let mut scratch = [0u8; 64];
        while let Ok(Some(_)) = sys::recv(&fd, &mut scratch) {}

        Ok(RawSocket {
            fd,
            info: InterfaceInfo {
                name: name.to_owned(),
                index,
                mtu,
                mac,
                brought_up,
                qdisc_bypass,
                promiscuous,
                warnings,
            },
            wait: opts.wait,
            stamped,
            last_rx: None,
        })
    }

    /// Facts about the interface.
    pub fn info(&self) -> &InterfaceInfo {
        &self.info
    }
}

impl Link for RawSocket {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        loop {
            match sys::send(&self.fd, frame) {
                Ok(n) if n == frame.len() => return Ok(()),
                Ok(n) => {
                    return Err(io::Error::other(format!(
                        "short send: {n} of {} bytes",
                        frame.len()
                    )))
                }
                // With PACKET_QDISC_BYPASS there is no queue: a full driver ring is reported
                // as ENOBUFS/EAGAIN. Retrying once the ring drains is the right thing here.
                Err(e)
                    if e.kind() == io::ErrorKind::WouldBlock
                        || e.raw_os_error() == Some(libc::ENOBUFS) =>
                {
                    std::hint::spin_loop();
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
    }

    fn recv(&mut self, buf: &mut [u8], deadline_ns: u64) -> io::Result<Option<usize>> {
        loop {
            let got = if self.stamped {
                sys::recv_stamped(&self.fd, buf)?
            } else {
                sys::recv(&self.fd, buf)?.map(|(c, f)| (c, f, None))
            };
            if let Some((_copied, full, stamp)) = got {
                // Realtime -> monotonic with the offset sampled now: robust to clock steps
                // (NTP slewing moves both clocks alike).
                self.last_rx = stamp.map(|rt| {
                    let offset = sys::realtime_ns().saturating_sub(clock::now_ns());
                    rt.saturating_sub(offset)
                });
                return Ok(Some(full));
            }
            let now = clock::now_ns();
            if now >= deadline_ns {
                return Ok(None);
            }
            match self.wait {
                WaitMode::Spin => std::hint::spin_loop(),
                WaitMode::Poll => {
                    sys::wait_readable(self.fd.as_raw_fd(), deadline_ns - now)?;
                }
            }
        }
    }

    fn last_rx_time(&self) -> Option<u64> {
        self.last_rx
    }
}
