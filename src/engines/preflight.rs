//! The pre-flight every method gives before it runs: what `granrepro run --explain` prints.
//!
//! Contract: [`Preflight::preflight`] reads only the stage's validated parameters (no input,
//! no solver run) and returns the method's stability table: every time scale of the scene
//! against the step (DEM: docs/definitions.md c.1, c.2), the CFL table (MPM), or why the
//! method has no explicit limit (CD). The same audit refuses an unstable step at load
//! (exit 2); this is its readable form.

/// A method's scene, audited before it runs.
pub trait Preflight {
    /// The stability table `run --explain` prints.
    fn preflight(&self) -> String;
}
