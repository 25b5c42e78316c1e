//! Property bodies for the wire area (see docs/verification.md).
