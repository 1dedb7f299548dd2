//! A virtual wafer stage: continuous-time truth with optional non-idealities, producing measured experiments. Owned by issue #7.
//!
//! This crate has no public API yet: nothing here pretends to work before its issue lands.
