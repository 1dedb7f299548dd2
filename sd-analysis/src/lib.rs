//! Closed-loop analysis: stability, sensitivities, margins, spectra, standstill simulation, intersample performance. Owned by issue #6.
//!
//! This crate has no public API yet: nothing here pretends to work before its issue lands.
