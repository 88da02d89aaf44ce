//! Topological order of a stage graph, with the cycle named when there is one. A leaf: it
//! knows stage ids and their inputs, not the pipeline's types.

use std::collections::HashMap;

/// Topological order of the stages `ids` (indices), inputs first, ties broken by file
/// order; `inputs[i]` are the ids stage `i` reads (ids not in `ids` are ignored). On a
/// cycle, returns the ids along it (first id repeated at the end).
pub fn topo_order(ids: &[&str], inputs: &[Vec<&str>]) -> Result<Vec<usize>, Vec<String>> {
    let idx: HashMap<&str, usize> = ids.iter().enumerate().map(|(i, s)| (*s, i)).collect();
    let deps: Vec<Vec<usize>> = inputs
        .iter()
        .map(|ins| ins.iter().filter_map(|d| idx.get(d).copied()).collect())
        .collect();
    // 0 = unvisited, 1 = on stack, 2 = done. Iterative DFS keeps file order stable.
    let mut state = vec![0u8; ids.len()];
    let mut order = Vec::with_capacity(ids.len());
    for root in 0..ids.len() {
        if state[root] != 0 {
            continue;
        }
        let mut stack: Vec<(usize, usize)> = vec![(root, 0)];
        state[root] = 1;
        while let Some(&mut (node, ref mut next)) = stack.last_mut() {
            if *next < deps[node].len() {
                let d = deps[node][*next];
                *next += 1;
                match state[d] {
                    0 => {
                        state[d] = 1;
                        stack.push((d, 0));
                    }
                    1 => {
                        let pos = stack.iter().position(|&(n, _)| n == d).unwrap();
                        let mut cycle: Vec<String> = stack[pos..].iter().map(|&(n, _)| ids[n].to_string()).collect();
                        // The stack runs consumer → input; print it in data-flow order.
                        cycle.reverse();
                        cycle.push(cycle[0].clone());
                        return Err(cycle);
                    }
                    _ => {}
                }
            } else {
                state[node] = 2;
                order.push(node);
                stack.pop();
            }
        }
    }
    Ok(order)
}
