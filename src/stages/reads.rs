//! What a kind with fixed inputs reads of them, whatever its params (`Kind::reads`): for
//! the committed store's serving rule and the load-time check of the inputs' outputs.

use crate::stages::kind::{Item, Read};

/// One `Read` of a whole table per (role, table).
pub fn tables(reads: &[(&str, &str)]) -> Vec<Read> {
    reads
        .iter()
        .map(|(role, table)| Read {
            role: role.to_string(),
            key: "(the kind's fixed reads)".to_string(),
            item: Item::Table(table.to_string()),
        })
        .collect()
}
