//! `ecdc-harness`: everything with I/O or `std` around the core: the ESC emulator, the
//! deterministic simulation driver, pcap capture, the Linux raw-socket runtime and the CLI.
