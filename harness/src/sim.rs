//! Deterministic simulation driver: a DC state machine and the emulated chain under simulated time.
