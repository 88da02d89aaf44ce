//! `granrepro plan --timings`: where a run's wall time went, read from the run records of
//! the cache entries of the stages' current keys (what `run` wrote, not a re-measurement):
//! - every stage's start (seconds after the first start), wall time and threads;
//! - the span, first start to last end, against the stages' own time (Σ wall × threads):
//!   how well the cores were kept busy;
//! - the critical chain: from the stage that ended last, back through the input that ended
//!   last, to a stage none of whose inputs ran in the same span. Shortening any other stage
//!   does not shorten the run.
//!
//! Stages served from the cache in a later run keep the record of the run that made them,
//! so read the table of a cold run (a fresh cache, `run` of everything) as the pipeline's
//! cost; entries made by different runs show up as gaps.

use serde_json::{Value, json};

use super::plan::plan;
use super::run::{Project, RunError};
use super::spec::Pipeline;

/// One stage's measured run.
#[derive(Debug, Clone, PartialEq)]
pub struct Timed {
    /// Stage id.
    pub id: String,
    /// Kind.
    pub kind: String,
    /// Start, seconds after the earliest start of the table.
    pub start_s: f64,
    /// Wall time [s].
    pub wall_s: f64,
    /// Threads of the stage's pool.
    pub threads: usize,
    /// Ids of its inputs.
    pub inputs: Vec<String>,
}

impl Timed {
    /// End, seconds after the earliest start.
    pub fn end_s(&self) -> f64 {
        self.start_s + self.wall_s
    }
}

/// The timings of a plan.
#[derive(Debug, Clone, Default)]
pub struct Timings {
    /// Stages with a run record, by start.
    pub rows: Vec<Timed>,
    /// Stages of the plan without an entry (never ran) or without a start time in its
    /// record (made by an older granrepro).
    pub missing: Vec<String>,
}

/// Read the run records of the stages `targets` need (all when empty).
pub fn timings(p: &Pipeline, proj: &Project, targets: &[String]) -> Result<Timings, RunError> {
    let mut rows = Vec::new();
    let mut missing = Vec::new();
    for st in plan(p, proj, targets)? {
        let rec: Option<Value> = std::fs::read(proj.cache.entry_dir(&st.key).join("record.json"))
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok());
        let got = rec.as_ref().and_then(|r| {
            Some((
                r.get("started_unix_s")?.as_f64()?,
                r.get("wall_s")?.as_f64()?,
                r.get("threads").and_then(Value::as_u64).unwrap_or(1),
            ))
        });
        match got {
            Some((start, wall, threads)) => rows.push(Timed {
                id: st.id,
                kind: st.kind,
                start_s: start,
                wall_s: wall,
                threads: threads.max(1) as usize,
                inputs: st.inputs,
            }),
            None => missing.push(st.id),
        }
    }
    Ok(Timings::new(rows, missing))
}

impl Timings {
    /// From rows with absolute starts (any origin): sorted by start, starts made relative
    /// to the earliest.
    pub fn new(mut rows: Vec<Timed>, missing: Vec<String>) -> Self {
        let t0 = rows.iter().map(|r| r.start_s).fold(f64::INFINITY, f64::min);
        for r in &mut rows {
            r.start_s -= t0;
        }
        rows.sort_by(|a, b| a.start_s.total_cmp(&b.start_s).then_with(|| a.id.cmp(&b.id)));
        Timings { rows, missing }
    }

    /// First start to last end [s].
    pub fn span_s(&self) -> f64 {
        self.rows.iter().map(Timed::end_s).fold(0.0, f64::max)
    }

    /// Σ wall × threads [s]: the core time the stages held.
    pub fn stage_core_s(&self) -> f64 {
        self.rows.iter().map(|r| r.wall_s * r.threads as f64).sum()
    }

    /// The critical chain, first stage first: the chain through inputs with the largest
    /// sum of wall times. With unlimited cores the run could not be shorter than this sum
    /// (wall times as measured, at their thread counts).
    pub fn critical_chain(&self) -> Vec<&Timed> {
        use std::collections::HashMap;
        let by_id: HashMap<&str, usize> = self.rows.iter().enumerate().map(|(k, r)| (r.id.as_str(), k)).collect();
        // Longest chain ending at each stage (the DAG is acyclic; memoised, inputs first).
        fn best(
            k: usize,
            rows: &[Timed],
            by_id: &HashMap<&str, usize>,
            memo: &mut Vec<Option<(f64, Option<usize>)>>,
        ) -> f64 {
            if let Some((v, _)) = memo[k] {
                return v;
            }
            let mut top = (0.0, None);
            for i in &rows[k].inputs {
                if let Some(&j) = by_id.get(i.as_str()) {
                    let v = best(j, rows, by_id, memo);
                    if v > top.0 {
                        top = (v, Some(j));
                    }
                }
            }
            let v = top.0 + rows[k].wall_s;
            memo[k] = Some((v, top.1));
            v
        }
        let mut memo = vec![None; self.rows.len()];
        let mut end = None;
        let mut longest = -1.0;
        for k in 0..self.rows.len() {
            let v = best(k, &self.rows, &by_id, &mut memo);
            if v > longest {
                longest = v;
                end = Some(k);
            }
        }
        let mut chain = Vec::new();
        while let Some(k) = end {
            chain.push(&self.rows[k]);
            end = memo[k].and_then(|(_, prev)| prev);
        }
        chain.reverse();
        chain
    }

    /// The report: stages at least `min_wall_s` long (all when 0), totals, the chain.
    pub fn to_text(&self, cores: usize, min_wall_s: f64) -> String {
        let mut s = String::new();
        s.push_str(&format!(
            "{:>9} {:>9} {:>9} {:>3}  {:<26} {}\n",
            "start [s]", "end [s]", "wall [s]", "thr", "kind", "stage"
        ));
        let mut hidden = (0usize, 0.0);
        for r in &self.rows {
            if r.wall_s < min_wall_s {
                hidden.0 += 1;
                hidden.1 += r.wall_s;
                continue;
            }
            s.push_str(&format!(
                "{:>9.1} {:>9.1} {:>9.2} {:>3}  {:<26} {}\n",
                r.start_s,
                r.end_s(),
                r.wall_s,
                r.threads,
                r.kind,
                r.id
            ));
        }
        if hidden.0 > 0 {
            s.push_str(&format!(
                "({} stages under {min_wall_s} s not listed: {:.1} s together)\n",
                hidden.0, hidden.1
            ));
        }
        let span = self.span_s();
        let held = self.stage_core_s();
        s.push_str(&format!(
            "\n{} stages; span {span:.1} s ({:.1} min); stage time Σ wall × threads {held:.1} s = {:.0} % of span × {cores} cores\n",
            self.rows.len(),
            span / 60.0,
            if span > 0.0 { 100.0 * held / (span * cores as f64) } else { 0.0 }
        ));
        let chain = self.critical_chain();
        let chain_s: f64 = chain.iter().map(|r| r.wall_s).sum();
        s.push_str(&format!(
            "lower bounds on the span: the critical chain {chain_s:.1} s (unlimited cores); Σ wall × threads / {cores} cores {:.1} s\n",
            held / cores as f64
        ));
        s.push_str("critical chain (the inputs chain with the largest Σ wall):\n");
        for r in chain {
            s.push_str(&format!("  {:>9.1} {:>9.2}  {}\n", r.start_s, r.wall_s, r.id));
        }
        if !self.missing.is_empty() {
            s.push_str(&format!(
                "no run record (not run, or an older granrepro made the entry): {}\n",
                self.missing.join(", ")
            ));
        }
        s
    }

    /// The same as one JSON document.
    pub fn to_json(&self, cores: usize) -> Value {
        json!({
            "span_s": self.span_s(),
            "stage_core_s": self.stage_core_s(),
            "cores": cores,
            "stages": self.rows.iter().map(|r| json!({"id": r.id, "kind": r.kind, "start_s": r.start_s, "wall_s": r.wall_s, "threads": r.threads})).collect::<Vec<_>>(),
            "critical_chain": self.critical_chain().iter().map(|r| r.id.clone()).collect::<Vec<_>>(),
            "missing": self.missing,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t(id: &str, start: f64, wall: f64, inputs: &[&str]) -> Timed {
        Timed {
            id: id.into(),
            kind: "k".into(),
            start_s: start,
            wall_s: wall,
            threads: 1,
            inputs: inputs.iter().map(|s| s.to_string()).collect(),
        }
    }

    #[test]
    fn the_chain_follows_the_input_that_ended_last() {
        // a (0–10) and b (0–30) feed c (30–35); e (35–40) reads c; d (10–50) is
        // independent and longest: the critical chain is d alone (40 s against b → c → e,
        // 40 s: ties keep the first found, so d is made 41 s). Without d: b → c → e
        // (a is shorter than b, so it is not critical).
        let rows = vec![
            t("a", 100.0, 10.0, &[]),
            t("b", 100.0, 30.0, &[]),
            t("c", 130.0, 5.0, &["a", "b"]),
            t("e", 135.0, 5.0, &["c"]),
            t("d", 110.0, 41.0, &[]),
        ];
        let tm = Timings::new(rows.clone(), vec![]);
        assert_eq!(tm.rows[0].start_s, 0.0);
        assert_eq!(tm.span_s(), 51.0);
        assert_eq!(tm.stage_core_s(), 91.0);
        assert_eq!(
            tm.critical_chain().iter().map(|r| r.id.as_str()).collect::<Vec<_>>(),
            ["d"]
        );
        let tm = Timings::new(rows.into_iter().filter(|r| r.id != "d").collect(), vec![]);
        assert_eq!(
            tm.critical_chain().iter().map(|r| r.id.as_str()).collect::<Vec<_>>(),
            ["b", "c", "e"]
        );
        let text = tm.to_text(2, 0.0);
        assert!(text.contains("span 40.0 s"), "{text}");
        assert!(
            text.contains("the critical chain 40.0 s (unlimited cores); Σ wall × threads / 2 cores 25.0 s"),
            "{text}"
        );
    }

    #[test]
    fn missing_records_are_listed_and_inputs_outside_the_table_ignored() {
        let tm = Timings::new(vec![t("c", 10.0, 5.0, &["not-timed"])], vec!["z".into()]);
        let chain: Vec<&str> = tm.critical_chain().iter().map(|r| r.id.as_str()).collect();
        assert_eq!(chain, ["c"]);
        assert!(
            tm.to_text(2, 0.0)
                .contains("no run record (not run, or an older granrepro made the entry): z")
        );
    }
}
