//! `granrepro plan --profile paper --estimate`: the CPU budget of a profile (placeholder).
use serde_json::Value;

use super::export::Measured;
use super::run::Project;
use super::spec::Pipeline;

/// Estimated cost of a profile.
#[derive(Debug, Clone, Default)]
pub struct Estimate {}

impl Estimate {
    /// JSON.
    pub fn to_json(&self) -> Value {
        Value::Null
    }
    /// Text.
    pub fn to_text(&self) -> String {
        String::new()
    }
    /// Estimated wall of one stage.
    pub fn measured(&self, _id: &str) -> Option<Measured> {
        None
    }
}

/// Estimate.
pub fn estimate(_p: &Pipeline, _proj: &Project, _targets: &[String]) -> Result<Estimate, String> {
    Ok(Estimate::default())
}
