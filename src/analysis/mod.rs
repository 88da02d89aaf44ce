//! Analyses shared by every method: flow front and height (D01, D03), energies, packing.
pub mod front;
pub mod pile;
