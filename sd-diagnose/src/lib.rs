//! Model-vs-data discrepancy diagnosis: detect, name the cause, extend the model, measure the gain. Owned by issue #8.
//!
//! This crate has no public API yet: nothing here pretends to work before its issue lands.
