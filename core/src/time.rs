//! Time types and wrap-safe arithmetic.
