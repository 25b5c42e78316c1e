//! A tiny blocking master over the emulator, for the comparison schemes: send a frame of
//! datagrams at a true time, wait for it to come back, parse the replies with `core::wire`.
//!
//! The comparison schemes are deliberately *not* built on ecdc's state machine (they must be
//! independent reproductions), so they talk to the [`Network`] through this one helper. Frames
//! are sent back to back: the next frame leaves `gap_ns` after the previous one came back, the
//! way a simple master polling in a loop would.

use anyhow::{anyhow, bail, Context};
use ecdc_core::wire::{Address, Command, EcatFrame, EthernetFrame, FrameBuilder};

use crate::emu::{Delivery, Network, TrueTime};

/// How long the master waits for a lost frame before going on: 100 µs, far above any
/// emulated round trip of these small frames, so a loss costs little time.
pub const LOSS_TIMEOUT_NS: u64 = 100_000;

/// Resends of a lost bring-up frame.
pub const RETRIES: u32 = 5;

/// One datagram of a reply.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reply {
    /// Data as returned.
    pub data: Vec<u8>,
    /// Working counter.
    pub wkc: u16,
}

/// The network plus the master's send cursor (true time).
#[derive(Debug)]
pub struct SimLink {
    /// The emulated chain.
    pub net: Network,
    /// Earliest true time the next frame may leave.
    pub now: TrueTime,
    /// Pause after a reply before the next frame (master software turnaround).
    pub gap_ns: u64,
    /// Frames sent.
    pub frames: u64,
    /// Frames lost.
    pub lost: u64,
    /// True time the last frame left the master.
    pub last_sent: TrueTime,
    buf: Vec<u8>,
}

impl SimLink {
    /// A link at true time 0 with a 2 µs turnaround.
    pub fn new(net: Network) -> Self {
        SimLink {
            now: net.now(),
            net,
            gap_ns: 2_000,
            frames: 0,
            lost: 0,
            last_sent: 0,
            buf: vec![0u8; 1514],
        }
    }

    /// Sends the FRMWs of a static drift burst with `frmw` until `sent` reaches `total` or the
    /// link reaches `until`, counting each frame in `sent` and `dist_frames`. True once the
    /// whole burst is sent.
    pub fn burst<R>(
        &mut self,
        sent: &mut u64,
        total: u64,
        dist_frames: &mut u64,
        until: TrueTime,
        mut frmw: impl FnMut(&mut SimLink) -> anyhow::Result<R>,
    ) -> anyhow::Result<bool> {
        while *sent < total && self.now < until {
            frmw(self)?;
            *sent += 1;
            *dist_frames += 1;
        }
        Ok(*sent >= total)
    }

    /// Lets the network run on, without frames, to `until` if it is not there yet (the end
    /// of a scheme's `advance`).
    pub fn advance_to(&mut self, until: TrueTime) -> anyhow::Result<()> {
        if until > self.net.now() {
            self.net.advance_to(until)?;
        }
        Ok(())
    }

    /// Sends one frame with `dgs` at `self.now` and returns the replies in order, or `None`
    /// if the frame was lost (the cursor then moves on by [`LOSS_TIMEOUT_NS`]).
    pub fn try_txn(
        &mut self,
        dgs: &[(Command, Address, &[u8])],
    ) -> anyhow::Result<Option<Vec<Reply>>> {
        let n = {
            let mut b = FrameBuilder::new(&mut self.buf).map_err(|e| anyhow!("{e:?}"))?;
            for (i, (c, a, d)) in dgs.iter().enumerate() {
                let idx = u8::try_from(i).unwrap_or(u8::MAX);
                b.push(*c, idx, *a, d).map_err(|e| anyhow!("{e:?}"))?;
            }
            b.finish().map_err(|e| anyhow!("{e:?}"))?
        };
        self.frames += 1;
        // Observers (clock samples) may have moved the network's time past our cursor.
        self.now = self.now.max(self.net.now());
        // A stalled master (`Fault::MasterStall`) sends nothing until the stall ends: the
        // same for every scheme as for ecdc's `Sim`.
        if let Some(end) = self.net.master_stalled(self.now) {
            self.now = end;
        }
        self.last_sent = self.now;
        let frame = self.buf[..n].to_vec();
        let r = match self.net.transact(&frame, self.now).context("emulator")? {
            Delivery::Returned(r) => r,
            Delivery::Lost(_) => {
                self.lost += 1;
                self.now += LOSS_TIMEOUT_NS;
                return Ok(None);
            }
        };
        self.now = r.arrival + self.gap_ns;
        let eth = EthernetFrame::new_checked(&r.frame[..]).map_err(|e| anyhow!("{e:?}"))?;
        let ecat = EcatFrame::new_checked(eth.payload()).map_err(|e| anyhow!("{e:?}"))?;
        let mut out = Vec::with_capacity(dgs.len());
        for d in ecat.iter() {
            let d = d.map_err(|e| anyhow!("{e:?}"))?;
            out.push(Reply {
                data: d.data().to_vec(),
                wkc: d.wkc(),
            });
        }
        if out.len() != dgs.len() {
            bail!("reply has {} datagrams, sent {}", out.len(), dgs.len());
        }
        Ok(Some(out))
    }

    /// [`SimLink::try_txn`], resending a lost frame up to [`RETRIES`] times.
    pub fn txn(&mut self, dgs: &[(Command, Address, &[u8])]) -> anyhow::Result<Vec<Reply>> {
        for _ in 0..=RETRIES {
            if let Some(r) = self.try_txn(dgs)? {
                return Ok(r);
            }
        }
        bail!(
            "frame lost {} times in a row at {} ns",
            RETRIES + 1,
            self.now
        )
    }

    /// One datagram; checks the working counter.
    pub fn one(
        &mut self,
        c: Command,
        a: Address,
        data: &[u8],
        want_wkc: u16,
    ) -> anyhow::Result<Vec<u8>> {
        let r = self.txn(&[(c, a, data)])?.remove(0);
        if r.wkc != want_wkc {
            bail!(
                "{c:?} {a:?}: working counter {} (expected {want_wkc})",
                r.wkc
            );
        }
        Ok(r.data)
    }
}

/// Little-endian u32 from the first 4 bytes (0 if shorter).
pub fn le_u32(d: &[u8]) -> u32 {
    d.get(..4)
        .and_then(|b| b.try_into().ok())
        .map(u32::from_le_bytes)
        .unwrap_or(0)
}

/// Little-endian u64 from the first 8 bytes (0 if shorter).
pub fn le_u64(d: &[u8]) -> u64 {
    d.get(..8)
        .and_then(|b| b.try_into().ok())
        .map(u64::from_le_bytes)
        .unwrap_or(0)
}
