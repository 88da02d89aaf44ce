//! The registry: every stage kind this build knows, gathered from the studies' lists
//! (`KINDS` in each study's `mod.rs`). A new kind is its own file plus two lines in its
//! study's `mod.rs` (the `pub mod` and the `KINDS` entry); nothing here changes.

use std::collections::BTreeMap;

use super::kind::Kind;
use super::{calib, column, generic, pile, work_precision};

/// Every stage kind this build knows, by name.
pub fn registry() -> BTreeMap<&'static str, Kind> {
    let studies = [
        generic::KINDS,
        column::KINDS,
        calib::KINDS,
        pile::KINDS,
        work_precision::KINDS,
    ];
    studies.into_iter().flatten().map(|k| (k.name, *k)).collect()
}

#[cfg(test)]
mod tests {
    use super::{calib, column, generic, pile, work_precision};

    /// The registry is a map by name: a second kind of one name would silently replace the
    /// first.
    #[test]
    fn kind_names_are_unique() {
        let mut names: Vec<&str> = [
            generic::KINDS,
            column::KINDS,
            calib::KINDS,
            pile::KINDS,
            work_precision::KINDS,
        ]
        .into_iter()
        .flatten()
        .map(|k| k.name)
        .collect();
        let n = names.len();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), n, "two kinds share a name");
        assert_eq!(super::registry().len(), n);
    }
}
