//! Runtime errors, each worded so the user knows what to do next.
//!
//! WHY a separate type: `anyhow` would carry the errno but not the fix. Every variant's
//! `Display` names the interface, what was observed and the command that resolves it.

use std::fmt;
use std::io;

/// What went wrong while opening or driving an interface.
#[derive(Debug)]
#[non_exhaustive]
pub enum RuntimeError {
    /// Opening the raw socket was refused (no CAP_NET_RAW).
    MissingCapability {
        /// The operation that was refused.
        op: &'static str,
    },
    /// The interface name is empty, too long or contains NUL.
    InvalidInterfaceName {
        /// The name given.
        name: String,
    },
    /// No interface has that name (in this network namespace).
    NoSuchInterface {
        /// The name given.
        name: String,
        /// Interfaces that do exist, to help with typos.
        available: Vec<String>,
    },
    /// The interface is administratively down and could not be brought up.
    InterfaceDown {
        /// Interface name.
        name: String,
        /// Why raising it failed.
        cause: io::Error,
    },
    /// The interface is up but has no carrier (cable, peer or veth end down).
    NoCarrier {
        /// Interface name.
        name: String,
    },
    /// Not an Ethernet interface.
    NotEthernet {
        /// Interface name.
        name: String,
        /// `ARPHRD_*` value reported by the kernel.
        hw_type: u16,
    },
    /// The MTU cannot carry the frames we need to send.
    MtuTooSmall {
        /// Interface name.
        name: String,
        /// Current MTU.
        mtu: u32,
        /// Ethernet payload bytes needed.
        need: u32,
    },
    /// Frames were sent but no slave processed any of them.
    NoSlaves {
        /// Interface name.
        name: String,
        /// Frames sent while probing.
        sent: u64,
        /// Frames received that were not answers (other traffic).
        ignored: u64,
    },
    /// Frames from another EtherCAT master were seen on the segment.
    OtherMaster {
        /// Interface name.
        name: String,
        /// That master's source MAC.
        mac: [u8; 6],
        /// How many of its frames were seen.
        frames: u64,
    },
    /// Any other system call failure.
    Io {
        /// What we were doing.
        op: &'static str,
        /// Interface name (may be empty).
        name: String,
        /// The OS error.
        source: io::Error,
    },
}

impl RuntimeError {
    /// Wraps an OS error, turning EPERM/EACCES into [`RuntimeError::MissingCapability`].
    pub fn os(op: &'static str, name: &str, source: io::Error) -> Self {
        match source.raw_os_error() {
            Some(libc::EPERM) | Some(libc::EACCES) => RuntimeError::MissingCapability { op },
            _ => RuntimeError::Io {
                op,
                name: name.to_owned(),
                source,
            },
        }
    }
}

/// Formats a MAC as `aa:bb:cc:dd:ee:ff`.
pub fn fmt_mac(mac: &[u8; 6]) -> String {
    let [a, b, c, d, e, f] = *mac;
    format!("{a:02x}:{b:02x}:{c:02x}:{d:02x}:{e:02x}:{f:02x}")
}

impl fmt::Display for RuntimeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RuntimeError::MissingCapability { op } => write!(
                f,
                "{op}: permission denied. Raw EtherCAT frames need CAP_NET_RAW (and CAP_NET_ADMIN to \
                 bring an interface up). Run as root, or grant the binary the capabilities once: \
                 `sudo setcap cap_net_raw,cap_net_admin+ep {}`",
                std::env::current_exe()
                    .map(|p| p.display().to_string())
                    .unwrap_or_else(|_| "$(command -v ecdc)".into())
            ),
            RuntimeError::InvalidInterfaceName { name } => write!(
                f,
                "invalid interface name {name:?}: must be 1..={} bytes without NUL",
                super::sys::IFNAME_MAX
            ),
            RuntimeError::NoSuchInterface { name, available } => {
                write!(f, "no interface named {name:?} in this network namespace")?;
                if available.is_empty() {
                    write!(f, " (and no interfaces listed in /sys/class/net)")
                } else {
                    write!(f, "; available: {}", available.join(", "))
                }
            }
            RuntimeError::InterfaceDown { name, cause } => write!(
                f,
                "interface {name} is down and could not be brought up ({cause}); run `ip link set {name} up` \
                 as root, or give ecdc CAP_NET_ADMIN"
            ),
            RuntimeError::NoCarrier { name } => write!(
                f,
                "interface {name} is up but has no link (no carrier): check the cable to the first slave's \
                 port 0, or that the other end of the veth pair is up"
            ),
            RuntimeError::NotEthernet { name, hw_type } => write!(
                f,
                "interface {name} is not Ethernet (ARPHRD type {hw_type}); EtherCAT needs an Ethernet port"
            ),
            RuntimeError::MtuTooSmall { name, mtu, need } => write!(
                f,
                "interface {name} has MTU {mtu}, EtherCAT needs {need} bytes of Ethernet payload: \
                 run `ip link set {name} mtu 1500`"
            ),
            RuntimeError::NoSlaves { name, sent, ignored } => write!(
                f,
                "no EtherCAT slave answered on {name} ({sent} frames sent, {ignored} unrelated frames \
                 ignored): check that slaves are powered and cabled to this port, or that `ecdc emulate` \
                 runs on the peer interface"
            ),
            RuntimeError::OtherMaster { name, mac, frames } => write!(
                f,
                "another EtherCAT master ({}) is sending on {name} ({frames} of its frames seen); two \
                 masters on one segment corrupt each other's datagrams: stop the other master first",
                fmt_mac(mac)
            ),
            RuntimeError::Io { op, name, source } => {
                if name.is_empty() {
                    write!(f, "{op}: {source}")
                } else {
                    write!(f, "{op} on {name}: {source}")
                }
            }
        }
    }
}

/// The `Display` text already contains the OS error, so no `source()` chain: `{:#}` in the
/// CLI would otherwise print it twice.
impl std::error::Error for RuntimeError {}
