//! Members of one pile sweep, joined: a `pile-run` stage swept over its list parameter
//! `energies_mgd` (`matrix: { energies_mgd: [..] }`, docs/pipeline.md) runs one energy per
//! member, ids `<stage>-energies_mgd<v>`, so that a sweep too long for one sitting is
//! cached in pieces. Its readers see one run per stage again: consecutive inputs of a role
//! that are members of the same stage form one group, in input (value) order.

use crate::pipeline::context::InputRef;

/// The stage a member of an `energies_mgd` sweep belongs to (None: not such a member).
fn swept_stage(inp: &InputRef) -> Option<&str> {
    inp.id.rsplit_once("-energies_mgd").map(|(b, _)| b)
}

/// The inputs of a role grouped by stage: each group one stage's run, its members joined.
pub fn by_stage(inputs: &[InputRef]) -> Vec<Vec<&InputRef>> {
    let mut out: Vec<Vec<&InputRef>> = Vec::new();
    for inp in inputs {
        match out.last_mut() {
            Some(g) if swept_stage(inp).is_some() && swept_stage(g[0]) == swept_stage(inp) => g.push(inp),
            _ => out.push(vec![inp]),
        }
    }
    out
}

/// Sort a joined run by energy: `e` ascending, and every column of `cols` (one value per
/// energy) in the same order.
pub fn sort_by_energy(e: &mut Vec<f64>, cols: &mut [&mut Vec<f64>]) {
    let mut order: Vec<usize> = (0..e.len()).collect();
    order.sort_by(|&a, &b| e[a].total_cmp(&e[b]));
    for v in std::iter::once(e).chain(cols.iter_mut().map(|c| &mut **c)) {
        *v = order.iter().map(|&i| v[i]).collect();
    }
}

#[cfg(test)]
mod tests {
    use super::by_stage;
    use crate::pipeline::context::InputRef;

    fn inp(id: &str) -> InputRef {
        InputRef { id: id.into(), dir: Default::default(), params: serde_json::Value::Null }
    }

    /// Members of one sweep join; a plain stage and another sweep stay apart.
    #[test]
    fn members_of_one_sweep_join() {
        let v = [
            inp("pile-dem-g"),
            inp("pile-cd-g-energies_mgd2.597"),
            inp("pile-cd-g-energies_mgd5.194"),
            inp("pile-cd-e00-energies_mgd12.85"),
            inp("pile-mpm-g"),
        ];
        let g: Vec<Vec<&str>> = by_stage(&v).iter().map(|g| g.iter().map(|i| i.id.as_str()).collect()).collect();
        assert_eq!(
            g,
            vec![
                vec!["pile-dem-g"],
                vec!["pile-cd-g-energies_mgd2.597", "pile-cd-g-energies_mgd5.194"],
                vec!["pile-cd-e00-energies_mgd12.85"],
                vec!["pile-mpm-g"],
            ]
        );
    }
}
