//! Property bodies for the dc_math area (see docs/verification.md).
