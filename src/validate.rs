//! Parameter validation shared by every stage kind and solver: a parameter struct reports
//! *all* its problems at once as [`Issue`]s, each naming the key, the offending value and
//! what is allowed, so the CLI can print them together (exit code 2) with file and line.

/// One invalid parameter value.
#[derive(Debug, Clone, PartialEq)]
pub struct Issue {
    /// Dotted key path inside the stage's params, e.g. `contact.restitution`.
    pub key: String,
    /// The value as the user gave it (rendered).
    pub value: String,
    /// What is allowed, as one phrase, e.g. `in (0, 1]` or `> 0 (a diameter)`.
    pub allowed: String,
}

/// Collects issues with small typed checks.
#[derive(Debug, Default)]
pub struct Checker {
    prefix: String,
    /// Issues found so far.
    pub issues: Vec<Issue>,
}

impl Checker {
    /// A checker whose keys are prefixed with `prefix.` (empty for none).
    pub fn new(prefix: &str) -> Self {
        Self {
            prefix: prefix.to_string(),
            issues: Vec::new(),
        }
    }
    fn key(&self, k: &str) -> String {
        if self.prefix.is_empty() {
            k.to_string()
        } else {
            format!("{}.{}", self.prefix, k)
        }
    }
    /// Record an issue unconditionally.
    pub fn fail(&mut self, key: &str, value: impl std::fmt::Display, allowed: &str) {
        let key = self.key(key);
        self.issues.push(Issue {
            key,
            value: value.to_string(),
            allowed: allowed.to_string(),
        });
    }
    /// `v` must be a finite number (not NaN or ±inf); records an issue and returns false
    /// otherwise.
    pub fn finite(&mut self, key: &str, v: f64) -> bool {
        if !v.is_finite() {
            self.fail(key, v, "must be a finite number (not NaN or infinity)");
        }
        v.is_finite()
    }
    /// `v` must be finite and > 0.
    pub fn positive(&mut self, key: &str, v: f64) {
        if self.finite(key, v) && v <= 0.0 {
            self.fail(key, v, "a finite number > 0");
        }
    }
    /// `v` must be finite and ≥ 0.
    pub fn non_negative(&mut self, key: &str, v: f64) {
        if self.finite(key, v) && v < 0.0 {
            self.fail(key, v, "a finite number >= 0");
        }
    }
    /// `v` must lie in the closed interval [lo, hi].
    pub fn in_closed(&mut self, key: &str, v: f64, lo: f64, hi: f64) {
        if self.finite(key, v) && !(v >= lo && v <= hi) {
            self.fail(key, v, &format!("in [{lo}, {hi}]"));
        }
    }
    /// `v` must lie in the half-open interval (lo, hi].
    pub fn in_open_closed(&mut self, key: &str, v: f64, lo: f64, hi: f64) {
        if self.finite(key, v) && !(v > lo && v <= hi) {
            self.fail(key, v, &format!("in ({lo}, {hi}]"));
        }
    }
    /// `v` must lie in the open interval (lo, hi).
    pub fn in_open(&mut self, key: &str, v: f64, lo: f64, hi: f64) {
        if self.finite(key, v) && !(v > lo && v < hi) {
            self.fail(key, v, &format!("in ({lo}, {hi})"));
        }
    }
    /// A physical quantity: finite and within the plausible range [lo, hi] of `what`
    /// (with its unit), e.g. `plausible("density", rho, 100.0, 2.5e4, "density [kg/m³]")`.
    /// The range is wide (orders of magnitude) — it catches typos and overflow, not
    /// unusual materials.
    pub fn plausible(&mut self, key: &str, v: f64, lo: f64, hi: f64, what: &str) {
        if self.finite(key, v) && !(v >= lo && v <= hi) {
            self.fail(key, v, &format!("a physically plausible {what} in [{lo:e}, {hi:e}]"));
        }
    }
    /// Generic condition with a custom message.
    pub fn check(&mut self, ok: bool, key: &str, value: impl std::fmt::Display, allowed: &str) {
        if !ok {
            self.fail(key, value, allowed);
        }
    }
    /// Merge the issues of a nested checker.
    pub fn extend(&mut self, other: Checker) {
        self.issues.extend(other.issues);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn non_finite_is_named_as_such() {
        let mut c = Checker::new("dem");
        c.positive("kn", f64::NAN);
        c.in_closed("mu", f64::INFINITY, 0.0, 1.0);
        c.plausible("density", 1e308, 100.0, 2.5e4, "density [kg/m³]");
        c.plausible("density", 2500.0, 100.0, 2.5e4, "density [kg/m³]");
        assert_eq!(c.issues.len(), 3);
        assert!(c.issues[0].allowed.contains("finite") && c.issues[0].key == "dem.kn");
        assert!(c.issues[1].allowed.contains("finite"));
        assert!(c.issues[2].allowed.contains("plausible density"));
    }
}
