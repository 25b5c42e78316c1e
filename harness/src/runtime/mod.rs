//! The Linux raw-socket runtime.
