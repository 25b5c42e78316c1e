//! A [`Link`] wrapper that records every frame sent and received into a pcap file
//! (`ecdc run --pcap`), with wall-clock timestamps so Wireshark shows real times.
//!
//! WHY at the link and not with tcpdump: with `PACKET_QDISC_BYPASS` our own TX frames are
//! invisible to captures on the interface (docs/background/linux-runtime.md §2); recording here sees both
//! directions whatever the socket options. Writing goes through a `BufWriter` (no allocation
//! per frame, a `write` syscall every 8 KiB); a write error stops recording and is reported
//! at the end instead of failing the real-time loop.

use std::fs::File;
use std::io::{self, BufWriter};

use super::clock;
use super::socket::Link;
use crate::capture::pcap::{PcapError, PcapWriter, TimeResolution};

/// Records a link's traffic into a pcap file.
#[derive(Debug)]
pub struct CaptureLink<L: Link> {
    inner: L,
    writer: Option<PcapWriter<BufWriter<File>>>,
    unix_offset_ns: u64,
    frames: u64,
    error: Option<PcapError>,
}

impl<L: Link> CaptureLink<L> {
    /// Wraps `inner`, creating `path` (nanosecond timestamps).
    pub fn create(inner: L, path: &std::path::Path) -> Result<Self, PcapError> {
        let writer = PcapWriter::create(path, TimeResolution::Nano)?;
        let wall = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
            .unwrap_or(0);
        Ok(CaptureLink {
            inner,
            writer: Some(writer),
            unix_offset_ns: wall.saturating_sub(clock::now_ns()),
            frames: 0,
            error: None,
        })
    }

    /// Wraps `inner` without recording (so callers need one link type either way).
    pub fn passthrough(inner: L) -> Self {
        CaptureLink {
            inner,
            writer: None,
            unix_offset_ns: 0,
            frames: 0,
            error: None,
        }
    }

    fn record(&mut self, frame: &[u8]) {
        if let Some(w) = self.writer.as_mut() {
            let ts = clock::now_ns().saturating_add(self.unix_offset_ns);
            match w.write_frame(ts, frame) {
                Ok(()) => self.frames += 1,
                Err(e) => {
                    self.error = Some(e);
                    self.writer = None;
                }
            }
        }
    }

    /// Flushes the file; returns frames written, or the first error.
    pub fn finish(&mut self) -> Result<u64, PcapError> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        if let Some(w) = self.writer.take() {
            w.finish()?;
        }
        Ok(self.frames)
    }

    /// The wrapped link.
    pub fn inner(&self) -> &L {
        &self.inner
    }
}

impl<L: Link> Link for CaptureLink<L> {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        self.inner.send(frame)?;
        self.record(frame);
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], deadline_ns: u64) -> io::Result<Option<usize>> {
        let got = self.inner.recv(buf, deadline_ns)?;
        if let Some(n) = got {
            // A truncated frame is recorded as far as it was read.
            let n = n.min(buf.len());
            self.record(buf.get(..n).unwrap_or_default());
        }
        Ok(got)
    }
}
