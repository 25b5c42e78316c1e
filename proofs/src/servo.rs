//! Property bodies for the servo area (see docs/verification.md).
