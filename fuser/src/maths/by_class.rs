//! Large windows fused a class per task: boxes of different classes never associate (CSBA-3D's
//! candidates are bucketed by class), so a window split by class and fused class by class on
//! rayon's threads gives the same groups, put back in the order one pass makes them.

use rayon::prelude::*;
use v2x_protocol::Detection;

/// A group's members as (agent, index in the agent's list): two to four agents need no
/// allocation per group.
pub type Members = smallvec::SmallVec<[(usize, usize); 4]>;

/// Windows with fewer boxes than this are fused in one pass: splitting would cost more than the
/// second core saves (16 agents x 100 boxes stay below it, 64 x 200 go above).
pub const PARALLEL_FROM: usize = 4096;

/// What one pass of CSBA-WLS returns: the fused boxes and the members of each.
pub type Groups = (Vec<Detection>, Vec<Members>);

/// `fuse` (one pass over the agents' lists, its groups in the order of their first members)
/// run class by class in parallel when the window holds at least [`PARALLEL_FROM`] boxes of two
/// classes or more and rayon has two threads; `None` otherwise, for the caller's one pass.
pub fn by_class<F>(agents: &[Vec<Detection>], fuse: F) -> Option<Groups>
where
    F: Fn(&[Vec<Detection>]) -> Groups + Sync,
{
    let n: usize = agents.iter().map(Vec::len).sum();
    if n < PARALLEL_FROM || rayon::current_num_threads() < 2 {
        return None;
    }
    let mut codes: Vec<u8> = agents.iter().flatten().map(|d| d.class.code()).collect();
    codes.sort_unstable();
    codes.dedup();
    if codes.len() < 2 {
        return None;
    }
    let parts: Vec<Groups> = codes
        .par_iter()
        .map(|&code| {
            // Each agent's boxes of this class, and where each stands in the agent's list.
            let (lists, places): (Vec<Vec<Detection>>, Vec<Vec<usize>>) = agents
                .iter()
                .map(|list| {
                    list.iter()
                        .enumerate()
                        .filter(|(_, d)| d.class.code() == code)
                        .map(|(j, d)| (d.clone(), j))
                        .unzip()
                })
                .unzip();
            let (fused, mut groups) = fuse(&lists);
            for member in groups.iter_mut().flat_map(|g| g.iter_mut()) {
                member.1 = places[member.0][member.1];
            }
            (fused, groups)
        })
        .collect();
    // One pass makes a group when its first member arrives: agent by agent, in list order.
    let mut all: Vec<(Detection, Members)> = parts
        .into_iter()
        .flat_map(|(fused, groups)| fused.into_iter().zip(groups))
        .collect();
    all.sort_unstable_by_key(|(_, g)| g[0]);
    Some(all.into_iter().unzip())
}
