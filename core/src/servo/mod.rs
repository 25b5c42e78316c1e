//! Clock servos.
