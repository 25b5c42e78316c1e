//! Opening the raw socket: the errors that need no special setup (no root, no netns).
//! The full socket path over veth is covered by scripts/netns-test.sh.

use ecdc_harness::runtime::errors::RuntimeError;
use ecdc_harness::runtime::socket::{RawSocket, SocketOptions};
use ecdc_harness::runtime::sys;

#[test]
fn unknown_interface_lists_the_existing_ones() {
    let err = RawSocket::open("ecdc-nope0", &SocketOptions::default()).unwrap_err();
    match &err {
        RuntimeError::NoSuchInterface { name, available } => {
            assert_eq!(name, "ecdc-nope0");
            assert!(available.iter().any(|n| n == "lo"), "{available:?}");
        }
        other => panic!("expected NoSuchInterface, got {other}"),
    }
    let text = err.to_string();
    assert!(
        text.contains("no interface named \"ecdc-nope0\"") && text.contains("lo"),
        "{text}"
    );
}

#[test]
fn invalid_names_are_rejected_before_any_syscall() {
    for bad in ["", "a-name-longer-than-15", "bad/name", "nul\0"] {
        match RawSocket::open(bad, &SocketOptions::default()) {
            Err(RuntimeError::InvalidInterfaceName { name }) => assert_eq!(name, bad),
            other => panic!("{bad:?}: expected InvalidInterfaceName, got {other:?}"),
        }
    }
}

#[test]
fn loopback_is_refused_as_not_ethernet_or_for_lack_of_capability() {
    // As root the socket opens and the hardware type check refuses loopback; without
    // CAP_NET_RAW the socket itself is refused with the setcap advice.
    match RawSocket::open("lo", &SocketOptions::default()) {
        Err(RuntimeError::NotEthernet { name, hw_type }) => {
            assert_eq!(name, "lo");
            assert_eq!(hw_type, libc::ARPHRD_LOOPBACK);
        }
        Err(e @ RuntimeError::MissingCapability { .. }) => {
            assert_ne!(sys::euid(), 0, "root should not lack CAP_NET_RAW here");
            assert!(
                e.to_string()
                    .contains("setcap cap_net_raw,cap_net_admin+ep"),
                "{e}"
            );
        }
        other => panic!("expected NotEthernet or MissingCapability, got {other:?}"),
    }
}

#[test]
fn permission_errors_map_to_the_capability_advice() {
    let e = RuntimeError::os(
        "opening AF_PACKET raw socket",
        "eth1",
        std::io::Error::from_raw_os_error(libc::EPERM),
    );
    assert!(matches!(e, RuntimeError::MissingCapability { .. }));
    let e = RuntimeError::os(
        "binding raw socket",
        "eth1",
        std::io::Error::from_raw_os_error(libc::ENETDOWN),
    );
    let text = e.to_string();
    assert!(text.contains("binding raw socket on eth1"), "{text}");
}
