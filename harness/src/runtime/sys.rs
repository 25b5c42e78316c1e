//! Every libc call the runtime makes, each behind a small safe function.
//!
//! WHY one module: the rest of the harness is `deny(unsafe_code)`; keeping all `unsafe` here
//! means one file to audit. Each function validates what it hands the kernel (buffer
//! lengths, NUL-terminated names, fully initialised structs) so the callers stay safe Rust.
//! Functions return `std::io::Error` with the raw `errno`; [`super::errors`] turns those into
//! messages a user can act on.
#![allow(unsafe_code)]

use std::ffi::CString;
use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd, RawFd};
use std::sync::atomic::{AtomicBool, Ordering};

/// Largest interface name the kernel accepts, without the trailing NUL (`IFNAMSIZ - 1`).
pub const IFNAME_MAX: usize = libc::IFNAMSIZ - 1;

fn cvt(ret: libc::c_int) -> io::Result<libc::c_int> {
    if ret < 0 {
        Err(io::Error::last_os_error())
    } else {
        Ok(ret)
    }
}

fn cvt_size(ret: libc::ssize_t) -> io::Result<usize> {
    usize::try_from(ret).map_err(|_| io::Error::last_os_error())
}

/// Opens a non-blocking, close-on-exec `AF_PACKET`/`SOCK_RAW` socket for one EtherType.
pub fn packet_socket(ethertype: u16) -> io::Result<OwnedFd> {
    // SAFETY: plain syscall with integer arguments; a non-negative return is a fresh fd that
    // nobody else owns, so wrapping it in OwnedFd (which closes it once) is sound.
    unsafe {
        let fd = cvt(libc::socket(
            libc::AF_PACKET,
            libc::SOCK_RAW | libc::SOCK_NONBLOCK | libc::SOCK_CLOEXEC,
            libc::c_int::from(ethertype.to_be()),
        ))?;
        Ok(OwnedFd::from_raw_fd(fd))
    }
}

/// Builds a zeroed `ifreq` carrying `name`; rejects names that do not fit or contain NUL.
fn ifreq_for(name: &str) -> io::Result<libc::ifreq> {
    let bytes = name.as_bytes();
    if bytes.is_empty() || bytes.len() > IFNAME_MAX || bytes.contains(&0) {
        return Err(io::Error::from_raw_os_error(libc::EINVAL));
    }
    // SAFETY: ifreq is a plain C struct/union of integers and arrays; all-zero is a valid value.
    let mut req: libc::ifreq = unsafe { std::mem::zeroed() };
    for (dst, src) in req.ifr_name.iter_mut().zip(bytes) {
        *dst = *src as libc::c_char;
    }
    Ok(req)
}

/// Interface index of `name` (`if_nametoindex`).
pub fn if_index(name: &str) -> io::Result<u32> {
    let c = CString::new(name).map_err(|_| io::Error::from_raw_os_error(libc::EINVAL))?;
    // SAFETY: `c` is a valid NUL-terminated string that outlives the call.
    let idx = unsafe { libc::if_nametoindex(c.as_ptr()) };
    if idx == 0 {
        Err(io::Error::last_os_error())
    } else {
        Ok(idx)
    }
}

/// Interface flags (`SIOCGIFFLAGS`): `IFF_UP`, `IFF_RUNNING`, `IFF_LOWER_UP` (as u32).
pub fn if_flags(fd: &OwnedFd, name: &str) -> io::Result<u32> {
    let mut req = ifreq_for(name)?;
    // SAFETY: SIOCGIFFLAGS reads ifr_name and writes ifr_flags inside `req`, which is a valid,
    // exclusively borrowed ifreq for the duration of the call.
    unsafe {
        cvt(libc::ioctl(fd.as_raw_fd(), libc::SIOCGIFFLAGS, &mut req))?;
        // ifr_flags is a c_short bit set; reinterpret as unsigned bits.
        Ok(u32::from(req.ifr_ifru.ifru_flags as u16))
    }
}

/// Sets the interface flags (`SIOCSIFFLAGS`); needs CAP_NET_ADMIN.
pub fn set_if_flags(fd: &OwnedFd, name: &str, flags: u32) -> io::Result<()> {
    let mut req = ifreq_for(name)?;
    req.ifr_ifru.ifru_flags = (flags & 0xFFFF) as u16 as libc::c_short;
    // SAFETY: SIOCSIFFLAGS only reads `req`, a valid ifreq with name and flags set.
    unsafe { cvt(libc::ioctl(fd.as_raw_fd(), libc::SIOCSIFFLAGS, &req)) }.map(drop)
}

/// Interface MTU (`SIOCGIFMTU`).
pub fn if_mtu(fd: &OwnedFd, name: &str) -> io::Result<u32> {
    let mut req = ifreq_for(name)?;
    // SAFETY: SIOCGIFMTU reads ifr_name and writes ifr_mtu of the exclusively borrowed `req`.
    unsafe {
        cvt(libc::ioctl(fd.as_raw_fd(), libc::SIOCGIFMTU, &mut req))?;
        Ok(u32::try_from(req.ifr_ifru.ifru_mtu).unwrap_or(0))
    }
}

/// Hardware address family (`ARPHRD_*`) and the first six address bytes (`SIOCGIFHWADDR`).
pub fn if_hwaddr(fd: &OwnedFd, name: &str) -> io::Result<(u16, [u8; 6])> {
    let mut req = ifreq_for(name)?;
    // SAFETY: SIOCGIFHWADDR reads ifr_name and writes the ifr_hwaddr sockaddr in `req`.
    let sa = unsafe {
        cvt(libc::ioctl(fd.as_raw_fd(), libc::SIOCGIFHWADDR, &mut req))?;
        req.ifr_ifru.ifru_hwaddr
    };
    let mut mac = [0u8; 6];
    for (dst, src) in mac.iter_mut().zip(sa.sa_data.iter()) {
        *dst = *src as u8;
    }
    Ok((sa.sa_family, mac))
}

/// Binds an `AF_PACKET` socket to one interface and EtherType.
pub fn bind_packet(fd: &OwnedFd, ifindex: u32, ethertype: u16) -> io::Result<()> {
    // SAFETY: sockaddr_ll is plain data; zeroed is valid and the fields we need are set below.
    let mut sll: libc::sockaddr_ll = unsafe { std::mem::zeroed() };
    sll.sll_family = libc::AF_PACKET as u16;
    sll.sll_protocol = ethertype.to_be();
    sll.sll_ifindex =
        i32::try_from(ifindex).map_err(|_| io::Error::from_raw_os_error(libc::EINVAL))?;
    let len = std::mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t;
    // SAFETY: we pass a pointer to a live sockaddr_ll and its exact size.
    unsafe {
        cvt(libc::bind(
            fd.as_raw_fd(),
            std::ptr::addr_of!(sll).cast::<libc::sockaddr>(),
            len,
        ))
    }
    .map(drop)
}

/// `setsockopt(fd, level, name, &int)`.
pub fn set_int_option(
    fd: &OwnedFd,
    level: libc::c_int,
    name: libc::c_int,
    value: libc::c_int,
) -> io::Result<()> {
    // SAFETY: the option value is a live c_int and we pass its exact size.
    unsafe {
        cvt(libc::setsockopt(
            fd.as_raw_fd(),
            level,
            name,
            std::ptr::addr_of!(value).cast::<libc::c_void>(),
            std::mem::size_of::<libc::c_int>() as libc::socklen_t,
        ))
    }
    .map(drop)
}

/// Adds a per-socket promiscuous membership (`PACKET_MR_PROMISC`). Unlike setting IFF_PROMISC
/// on the interface, the kernel drops it again when the socket closes, even after a crash.
pub fn add_promisc_membership(fd: &OwnedFd, ifindex: u32) -> io::Result<()> {
    // SAFETY: packet_mreq is plain data; zeroed is valid.
    let mut mreq: libc::packet_mreq = unsafe { std::mem::zeroed() };
    mreq.mr_ifindex =
        i32::try_from(ifindex).map_err(|_| io::Error::from_raw_os_error(libc::EINVAL))?;
    mreq.mr_type = libc::PACKET_MR_PROMISC as u16;
    // SAFETY: pointer to a live packet_mreq with its exact size.
    unsafe {
        cvt(libc::setsockopt(
            fd.as_raw_fd(),
            libc::SOL_PACKET,
            libc::PACKET_ADD_MEMBERSHIP,
            std::ptr::addr_of!(mreq).cast::<libc::c_void>(),
            std::mem::size_of::<libc::packet_mreq>() as libc::socklen_t,
        ))
    }
    .map(drop)
}

/// Sends one complete Ethernet frame on a bound packet socket; returns bytes sent.
pub fn send(fd: &OwnedFd, frame: &[u8]) -> io::Result<usize> {
    // SAFETY: the pointer and length describe the live, borrowed `frame` slice.
    cvt_size(unsafe {
        libc::send(
            fd.as_raw_fd(),
            frame.as_ptr().cast::<libc::c_void>(),
            frame.len(),
            libc::MSG_DONTWAIT,
        )
    })
}

/// Non-blocking receive. Returns `Ok(None)` when nothing is queued, else
/// `(bytes copied, full frame length)`; the second is larger when the frame was truncated.
pub fn recv(fd: &OwnedFd, buf: &mut [u8]) -> io::Result<Option<(usize, usize)>> {
    // SAFETY: the pointer and length describe the live, exclusively borrowed `buf`; the kernel
    // writes at most buf.len() bytes. MSG_TRUNC only changes the returned length.
    let ret = unsafe {
        libc::recv(
            fd.as_raw_fd(),
            buf.as_mut_ptr().cast::<libc::c_void>(),
            buf.len(),
            libc::MSG_DONTWAIT | libc::MSG_TRUNC,
        )
    };
    match cvt_size(ret) {
        Ok(full) => Ok(Some((full.min(buf.len()), full))),
        Err(e) if e.kind() == io::ErrorKind::WouldBlock => Ok(None),
        Err(e) if e.kind() == io::ErrorKind::Interrupted => Ok(None),
        Err(e) => Err(e),
    }
}

/// Asks the kernel to stamp every received frame (`SO_TIMESTAMPNS`, `CLOCK_REALTIME` in ns),
/// read back with [`recv_stamped`].
pub fn enable_rx_timestamps(fd: &OwnedFd) -> io::Result<()> {
    set_int_option(fd, libc::SOL_SOCKET, libc::SO_TIMESTAMPNS, 1)
}

/// Like [`recv`], plus the kernel receive time (`CLOCK_REALTIME` ns) when the socket has
/// [`enable_rx_timestamps`] set and the kernel attached one.
pub fn recv_stamped(
    fd: &OwnedFd,
    buf: &mut [u8],
) -> io::Result<Option<(usize, usize, Option<u64>)>> {
    // Room for one timespec control message (CMSG_SPACE(16) = 32 on 64-bit), u64-aligned.
    let mut control = [0u64; 8];
    let mut iov = libc::iovec {
        iov_base: buf.as_mut_ptr().cast::<libc::c_void>(),
        iov_len: buf.len(),
    };
    // SAFETY: msghdr is plain data; zeroed is valid (null name, no flags).
    let mut msg: libc::msghdr = unsafe { std::mem::zeroed() };
    msg.msg_iov = &mut iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control.as_mut_ptr().cast::<libc::c_void>();
    msg.msg_controllen = std::mem::size_of_val(&control);
    // SAFETY: `msg` points at one live iovec describing the exclusively borrowed `buf` and at
    // the live `control` array with its exact size; the kernel writes within those bounds.
    let ret = unsafe {
        libc::recvmsg(
            fd.as_raw_fd(),
            &mut msg,
            libc::MSG_DONTWAIT | libc::MSG_TRUNC,
        )
    };
    let full = match cvt_size(ret) {
        Ok(n) => n,
        Err(e)
            if e.kind() == io::ErrorKind::WouldBlock || e.kind() == io::ErrorKind::Interrupted =>
        {
            return Ok(None)
        }
        Err(e) => return Err(e),
    };
    let mut stamp = None;
    // SAFETY: CMSG_FIRSTHDR/CMSG_NXTHDR walk the control buffer the kernel filled, using
    // msg_controllen it set (never more than our buffer); each header is checked for level,
    // type and length before its 16-byte timespec payload is copied out unaligned.
    unsafe {
        let mut cmsg = libc::CMSG_FIRSTHDR(&msg);
        while !cmsg.is_null() {
            let c = &*cmsg;
            if c.cmsg_level == libc::SOL_SOCKET
                && c.cmsg_type == libc::SCM_TIMESTAMPNS
                && c.cmsg_len as usize
                    >= libc::CMSG_LEN(std::mem::size_of::<libc::timespec>() as u32) as usize
            {
                let ts: libc::timespec =
                    std::ptr::read_unaligned(libc::CMSG_DATA(cmsg).cast::<libc::timespec>());
                let secs = u64::try_from(ts.tv_sec).unwrap_or(0);
                let nanos = u64::try_from(ts.tv_nsec).unwrap_or(0);
                stamp = Some(secs.saturating_mul(1_000_000_000).saturating_add(nanos));
            }
            cmsg = libc::CMSG_NXTHDR(&msg, cmsg);
        }
    }
    Ok(Some((full.min(buf.len()), full, stamp)))
}

/// `CLOCK_REALTIME` in nanoseconds (only to convert kernel receive stamps).
pub fn realtime_ns() -> u64 {
    clock_ns(libc::CLOCK_REALTIME)
}

/// `clock` (one that `clock_gettime` cannot fail for) in nanoseconds.
fn clock_ns(clock: libc::clockid_t) -> u64 {
    // SAFETY: timespec is plain data; clock_gettime writes it.
    let mut ts: libc::timespec = unsafe { std::mem::zeroed() };
    // SAFETY: `ts` is a live, exclusively borrowed timespec.
    unsafe { libc::clock_gettime(clock, &mut ts) };
    let secs = u64::try_from(ts.tv_sec).unwrap_or(0);
    let nanos = u64::try_from(ts.tv_nsec).unwrap_or(0);
    secs.saturating_mul(1_000_000_000).saturating_add(nanos)
}

/// Waits until `fd` is readable or `timeout_ns` passes (`ppoll`, nanosecond timeout).
/// Returns whether it became readable. EINTR counts as "not readable yet".
pub fn wait_readable(fd: RawFd, timeout_ns: u64) -> io::Result<bool> {
    let mut pfd = libc::pollfd {
        fd,
        events: libc::POLLIN,
        revents: 0,
    };
    let ts = timespec_from_ns(timeout_ns);
    // SAFETY: one live pollfd, a live timespec, no signal mask.
    let ret = unsafe { libc::ppoll(&mut pfd, 1, &ts, std::ptr::null()) };
    if ret < 0 {
        let e = io::Error::last_os_error();
        if e.kind() == io::ErrorKind::Interrupted {
            return Ok(false);
        }
        return Err(e);
    }
    Ok(ret > 0)
}

fn timespec_from_ns(ns: u64) -> libc::timespec {
    libc::timespec {
        tv_sec: libc::time_t::try_from(ns / 1_000_000_000).unwrap_or(libc::time_t::MAX),
        // < 1e9, always fits.
        tv_nsec: (ns % 1_000_000_000) as libc::c_long,
    }
}

/// `CLOCK_MONOTONIC` in nanoseconds.
pub fn monotonic_ns() -> u64 {
    clock_ns(libc::CLOCK_MONOTONIC)
}

/// Sleeps until the absolute `CLOCK_MONOTONIC` time `deadline_ns` (`TIMER_ABSTIME`: no drift
/// from accumulated relative sleeps). Returns early with `Ok(false)` only if a signal
/// interrupted it and `stop` is set, so Ctrl-C is handled promptly.
pub fn sleep_until(deadline_ns: u64, stop: &AtomicBool) -> bool {
    let ts = timespec_from_ns(deadline_ns);
    loop {
        // SAFETY: live timespec; remaining-time pointer may be null with TIMER_ABSTIME.
        let ret = unsafe {
            libc::clock_nanosleep(
                libc::CLOCK_MONOTONIC,
                libc::TIMER_ABSTIME,
                &ts,
                std::ptr::null_mut(),
            )
        };
        if ret == libc::EINTR {
            if stop.load(Ordering::Relaxed) {
                return false;
            }
            continue;
        }
        return true;
    }
}

/// Puts the calling thread under `SCHED_FIFO` with `priority`.
pub fn set_fifo(priority: i32) -> io::Result<()> {
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: pthread_self() is always valid for the calling thread; `param` is live.
    let ret =
        unsafe { libc::pthread_setschedparam(libc::pthread_self(), libc::SCHED_FIFO, &param) };
    if ret == 0 {
        Ok(())
    } else {
        Err(io::Error::from_raw_os_error(ret))
    }
}

/// Locks current and future pages in RAM so the loop never takes a major page fault.
pub fn mlockall() -> io::Result<()> {
    // SAFETY: flag-only syscall.
    unsafe { cvt(libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE)) }.map(drop)
}

/// Pins the calling thread to one CPU.
pub fn pin_to_cpu(cpu: usize) -> io::Result<()> {
    if cpu >= libc::CPU_SETSIZE as usize {
        return Err(io::Error::from_raw_os_error(libc::EINVAL));
    }
    // SAFETY: cpu_set_t is a plain bit array; zeroed is the empty set. CPU_SET is given an
    // index checked against CPU_SETSIZE above. sched_setaffinity reads the live set.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(cpu, &mut set);
        cvt(libc::sched_setaffinity(
            0,
            std::mem::size_of::<libc::cpu_set_t>(),
            &set,
        ))
        .map(drop)
    }
}

/// Sets this thread's timer slack. The default 50 us slack for SCHED_OTHER threads would
/// otherwise let the kernel delay every `clock_nanosleep`/`ppoll` wake-up by that much.
pub fn set_timer_slack_ns(ns: u64) -> io::Result<()> {
    let arg = libc::c_ulong::try_from(ns.max(1)).unwrap_or(1);
    // SAFETY: PR_SET_TIMERSLACK takes one integer argument; the rest are ignored.
    unsafe { cvt(libc::prctl(libc::PR_SET_TIMERSLACK, arg, 0, 0, 0)) }.map(drop)
}

/// Number of CPUs online.
pub fn cpus_online() -> usize {
    // SAFETY: sysconf with a valid name has no memory effects.
    let n = unsafe { libc::sysconf(libc::_SC_NPROCESSORS_ONLN) };
    usize::try_from(n).unwrap_or(1).max(1)
}

/// Effective user id (only used to word error messages).
pub fn euid() -> u32 {
    // SAFETY: geteuid cannot fail and has no memory effects.
    unsafe { libc::geteuid() }
}

static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_stop_signal(_sig: libc::c_int) {
    // Only an atomic store: async-signal-safe.
    STOP.store(true, Ordering::Relaxed);
}

/// Installs SIGINT/SIGTERM handlers that set a flag instead of killing the process, so loops
/// can stop cleanly and print their summary. Returns the flag. `SA_RESTART` is deliberately
/// not set: a blocked sleep or poll returns EINTR and the loop sees the flag at once.
pub fn install_stop_handler() -> io::Result<&'static AtomicBool> {
    for sig in [libc::SIGINT, libc::SIGTERM] {
        // SAFETY: sigaction is plain data; zeroed gives an empty mask and no flags. The handler
        // is an `extern "C" fn(c_int)` that only touches an atomic, which is async-signal-safe.
        unsafe {
            let mut sa: libc::sigaction = std::mem::zeroed();
            sa.sa_sigaction = on_stop_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
            libc::sigemptyset(&mut sa.sa_mask);
            cvt(libc::sigaction(sig, &sa, std::ptr::null_mut()))?;
        }
    }
    Ok(&STOP)
}

/// Restores the default action of SIGPIPE (end the process), which the Rust runtime sets to
/// "ignore": then `ecdc decode big.pcap | head` ends quietly when `head` closes the pipe, as
/// other Unix tools do, instead of panicking on the next `println!` (EPIPE). The raw socket
/// never raises SIGPIPE (only pipes and stream sockets do).
pub fn default_sigpipe() -> io::Result<()> {
    // SAFETY: sigaction is plain data; zeroed gives an empty mask and no flags, and SIG_DFL
    // is a valid disposition for SIGPIPE.
    unsafe {
        let mut sa: libc::sigaction = std::mem::zeroed();
        sa.sa_sigaction = libc::SIG_DFL;
        libc::sigemptyset(&mut sa.sa_mask);
        cvt(libc::sigaction(libc::SIGPIPE, &sa, std::ptr::null_mut()))?;
    }
    Ok(())
}
