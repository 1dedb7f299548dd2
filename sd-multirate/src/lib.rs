//! Lemma 6 downsampling, rate-tied non-ideal holds and samplers, lifting and multirate (LPTV) frequency analysis. Owned by issue #3.
//!
//! This crate has no public API yet: nothing here pretends to work before its issue lands.
