//! What a stage names of its inputs, checked at load against what their kinds declare
//! they publish ([`crate::stages::kind::Outputs`]).
//!
//! Contract: a `plot` whose series reads `y: runout_nrom` of a `column-collapse` input, or a
//! ledger row whose `measure.scalar` is not a scalar its stage's kind publishes, is refused
//! before any stage runs, naming the file, the key and the nearest declared name. The
//! runner holds each kind to its declaration (see [`undeclared`]), so a name accepted here
//! is one the input can publish.

use std::path::PathBuf;

use crate::pipeline::context::Output;
use crate::stages::kind::{Item, Kind, Outputs, Read};

/// A read located in the file that wrote its key.
#[derive(Debug, Clone)]
pub struct Located {
    /// The read.
    pub read: Read,
    /// The file whose layer set the key.
    pub file: PathBuf,
    /// Its line there.
    pub line: Option<usize>,
}

/// One refused read: (file, line, key, message, help).
pub type Refusal = (PathBuf, Option<usize>, String, String, String);

/// Check the reads of one stage against the kinds of its resolved inputs. `kind_of`
/// gives an input stage's id → its kind.
pub fn check<'a>(
    stage: &str,
    reads: &[Located],
    inputs: &[(String, Vec<String>)],
    kind_of: impl Fn(&str) -> Option<&'a Kind>,
) -> Vec<Refusal> {
    let mut out: Vec<Refusal> = Vec::new();
    for l in reads {
        let Some((_, ids)) = inputs.iter().find(|(r, _)| *r == l.read.role) else {
            continue; // a missing role is the roles check's to report
        };
        // Each distinct input kind once: a sweep's members share theirs.
        let mut seen: Vec<&str> = Vec::new();
        for id in ids {
            let Some(kind) = kind_of(id) else { continue };
            if seen.contains(&kind.name) {
                continue;
            }
            seen.push(kind.name);
            if let Some((message, help)) = refuse(&l.read.item, &kind.outputs) {
                out.push((
                    l.file.clone(),
                    l.line,
                    format!("stages[{stage}].params.{}", l.read.key),
                    format!(
                        "{message}, which kind `{}` (input `{}`: {id}) does not publish",
                        kind.name, l.read.role
                    ),
                    help,
                ));
            }
        }
    }
    out
}

/// Why `item` is not among `outputs`: (message, help), or None when it is declared.
pub fn refuse(item: &Item, o: &Outputs) -> Option<(String, String)> {
    let names = |v: &[&str]| v.iter().map(|s| format!("`{s}`")).collect::<Vec<_>>().join(", ");
    let tables: Vec<&str> = o.tables.iter().map(|t| t.name).collect();
    match item {
        Item::Scalar(s) if !o.has_scalar(s) => Some((
            format!("scalar `{s}`"),
            suggest(s, o.scalars, "its scalars", &names(o.scalars)),
        )),
        Item::Table(t) if o.table(t).is_none() => Some((
            format!("table `{t}`"),
            suggest(t, &tables, "its tables", &names(&tables)),
        )),
        Item::Column(t, c) | Item::ColumnOrScalar(t, c) => {
            let or_scalar = matches!(item, Item::ColumnOrScalar(..)) && o.has_scalar(c);
            match o.table(t) {
                None => Some((
                    format!("table `{t}`"),
                    suggest(t, &tables, "its tables", &names(&tables)),
                )),
                Some(decl) if !or_scalar && !o.has_column(t, c) => {
                    let what = if matches!(item, Item::ColumnOrScalar(..)) {
                        format!("column (or scalar) `{c}` of table `{t}`")
                    } else {
                        format!("column `{c}` of table `{t}`")
                    };
                    Some((what, suggest(c, decl.columns, "its columns", &names(decl.columns))))
                }
                _ => None,
            }
        }
        _ => None,
    }
}

/// "did you mean `x`?" when one declared name is close, else the whole list.
fn suggest(name: &str, declared: &[&str], what: &str, list: &str) -> String {
    let best = declared
        .iter()
        .map(|d| (distance(name, d.trim_end_matches('*')), *d))
        .min_by_key(|(k, _)| *k);
    match best {
        Some((k, d)) if k <= 3.max(name.len() / 4) => format!("did you mean `{d}`? {what}: {list}"),
        _ if declared.is_empty() => format!("it publishes no {}", what.trim_start_matches("its ")),
        _ => format!("{what}: {list}"),
    }
}

/// Levenshtein distance (short names only).
fn distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let cur = row[j + 1];
            row[j + 1] = (prev + usize::from(ca != *cb)).min(row[j] + 1).min(cur + 1);
            prev = cur;
        }
    }
    row[b.len()]
}

/// What a run published beyond its kind's declaration: one line per undeclared scalar,
/// table, column or measurement (empty when the run kept to it). The runner refuses such
/// a run, so a declaration cannot fall behind its kind.
pub fn undeclared(kind: &Kind, out: &Output) -> Vec<String> {
    let o = &kind.outputs;
    let mut bad = Vec::new();
    for s in out.scalars.keys() {
        if !o.has_scalar(s) {
            bad.push(format!("scalar `{s}`"));
        }
    }
    for (t, df) in &out.tables {
        if o.table(t).is_none() {
            bad.push(format!("table `{t}`"));
            continue;
        }
        for c in df.get_column_names() {
            if !o.has_column(t, c.as_str()) {
                bad.push(format!("column `{c}` of table `{t}`"));
            }
        }
    }
    for c in &out.claims {
        if !o.has_measurement(&c.id) {
            bad.push(format!("measurement `{}`", c.id));
        }
    }
    for t in out.texts.keys() {
        if !o.has_text(t) {
            bad.push(format!("text `{t}`"));
        }
    }
    bad
}

/// [`undeclared`] as the runner's verdict: Err names the kind and what to declare.
pub fn require_declared(kind: &Kind, out: &Output) -> Result<(), String> {
    let bad = undeclared(kind, out);
    if bad.is_empty() {
        return Ok(());
    }
    Err(format!(
        "internal error: kind `{}` published what its declaration does not list ({}); add it to the kind's `outputs`",
        kind.name,
        bad.join(", ")
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stages::kind::TableDecl;

    const OUT: Outputs = Outputs {
        scalars: &["runout_norm", "l0_m", "energy_at_*"],
        tables: &[TableDecl {
            name: "series",
            columns: &["t_s", "l_m"],
        }],
        measurements: &["col-runout"],
        texts: &[],
    };

    #[test]
    fn declared_names_and_families_pass() {
        assert!(refuse(&Item::Scalar("runout_norm".into()), &OUT).is_none());
        assert!(refuse(&Item::Scalar("energy_at_3tau".into()), &OUT).is_none());
        assert!(refuse(&Item::Column("series".into(), "t_s".into()), &OUT).is_none());
        assert!(refuse(&Item::ColumnOrScalar("series".into(), "l0_m".into()), &OUT).is_none());
    }

    #[test]
    fn a_misspelt_name_is_refused_with_the_nearest() {
        let (m, help) = refuse(&Item::Scalar("runout_nrom".into()), &OUT).unwrap();
        assert!(m.contains("runout_nrom"), "{m}");
        assert!(help.starts_with("did you mean `runout_norm`?"), "{help}");
        assert!(refuse(&Item::Table("serie".into()), &OUT).is_some());
        assert!(refuse(&Item::Column("series".into(), "h_m".into()), &OUT).is_some());
        assert!(refuse(&Item::ColumnOrScalar("series".into(), "h_m".into()), &OUT).is_some());
    }
}
