//! Property bodies for the machine area (see docs/verification.md).
