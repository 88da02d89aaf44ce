//! Which method runs a study: the `method:` field of a study kind's params.

use serde::{Deserialize, Serialize};

/// The three methods of the chapter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Soft-contact DEM (`src/dem`).
    Dem,
    /// Contact Dynamics (`src/cd`).
    Cd,
    /// GIMP MPM, Mohr–Coulomb (`src/mpm`).
    Mpm,
}

impl Method {
    /// Label, as the chapter writes it.
    pub fn label(self) -> &'static str {
        match self {
            Method::Dem => "DEM",
            Method::Cd => "CD",
            Method::Mpm => "MPM",
        }
    }
    /// The value of the `method:` field.
    pub fn key(self) -> &'static str {
        match self {
            Method::Dem => "dem",
            Method::Cd => "cd",
            Method::Mpm => "mpm",
        }
    }
    /// Palette index of the method in the charts.
    pub fn color(self) -> usize {
        match self {
            Method::Dem => 0,
            Method::Cd => 2,
            Method::Mpm => 1,
        }
    }
    /// Parse the `method:` value.
    pub fn parse(s: &str) -> Option<Method> {
        [Method::Dem, Method::Cd, Method::Mpm]
            .into_iter()
            .find(|m| m.key() == s)
    }
}

#[cfg(test)]
mod tests {
    use super::Method;

    #[test]
    fn key_round_trips_through_serde_and_parse() {
        for m in [Method::Dem, Method::Cd, Method::Mpm] {
            assert_eq!(Method::parse(m.key()), Some(m));
            assert_eq!(serde_json::to_value(m).unwrap(), serde_json::json!(m.key()));
        }
        assert_eq!(Method::parse("fem"), None);
    }
}
