//! The ESC emulator.
