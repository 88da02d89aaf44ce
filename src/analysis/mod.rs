//! Analyses shared by every method: flow front and height (D01, D03), energies, packing.
pub mod cloud;
pub mod failure;
pub mod front;
pub mod gathered_front;
pub mod inertial;
pub mod pile;
pub mod runout;
pub mod stop;
pub mod thick_front;
pub mod voronoi;
