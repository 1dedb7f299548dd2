//! Riccati solvers (DARE, CARE) and discrete-time McFarlane-Glover loopshaping. Owned by issue #4.
//!
//! This crate has no public API yet: nothing here pretends to work before its issue lands.
