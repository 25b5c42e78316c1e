//! Distributed Clocks: the pure maths (topology, propagation delays, offsets, SYNC start) and
//! the sans-IO bring-up and cyclic state machine.
//!
//! Pipeline: discover → latch receive times → delays → offsets → static drift compensation →
//! SYNC0/SYNC1 start → cyclic drift compensation and monitoring.

// --- DC maths (owner: DC maths engineer): pure functions the machine calls ---
pub mod delay;
pub mod offset;
pub mod port;
pub mod sync;
pub mod topology;
