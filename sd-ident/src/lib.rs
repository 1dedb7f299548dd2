//! Multisine design, FRF estimation (periodic, closed loop, LPM) with variances, and discrete-time rational fitting. Owned by issue #5.
//!
//! This crate has no public API yet: nothing here pretends to work before its issue lands.
