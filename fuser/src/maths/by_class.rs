//! Large windows fused a class per task: boxes of different classes never associate (CSBA-3D's
//! candidates are bucketed by class), so a window split by class and fused class by class on
//! rayon's threads gives the same groups, put back in the order one pass makes them.

use crate::maths::method::Members;
use rayon::prelude::*;
use v2x_protocol::Detection;

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::maths::association::CsbaParams;
    use crate::maths::method::csba_groups;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use v2x_protocol::fixtures::{car, URBAN_MIX};

    /// `agents` noisy views of `n` objects of the urban mix (1 m position noise).
    fn window(n: usize, agents: usize, seed: u64) -> Vec<Vec<Detection>> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let truth: Vec<Detection> = (0..n)
            .map(|i| {
                let mut d = car(
                    rng.gen_range(-300.0..300.0),
                    rng.gen_range(-300.0..300.0),
                    1.0,
                );
                d.class = URBAN_MIX[i % URBAN_MIX.len()];
                d.size = d.class.typical_size();
                d
            })
            .collect();
        (0..agents)
            .map(|_| {
                let mut seen = Vec::new();
                for d in &truth {
                    if rng.gen_bool(0.9) {
                        let mut d = d.clone();
                        d.center[0] += rng.gen_range(-1.5..1.5);
                        d.center[1] += rng.gen_range(-1.5..1.5);
                        seen.push(d);
                    }
                }
                seen
            })
            .collect()
    }

    #[test]
    fn a_window_fused_class_by_class_equals_one_pass() {
        let p = CsbaParams::default();
        let one_pass = |a: &[Vec<Detection>]| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(1)
                .build()
                .unwrap();
            pool.install(|| csba_groups(&p, a))
        };
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        for seed in [1, 2] {
            let agents = window(300, 16, seed);
            assert!(agents.iter().map(Vec::len).sum::<usize>() >= PARALLEL_FROM);
            let split = pool.install(|| by_class(&agents, one_pass)).expect("split");
            let whole = one_pass(&agents);
            assert_eq!(split.1, whole.1, "seed {seed}");
            assert_eq!(split.0, whole.0, "seed {seed}");
            assert!(whole.1.iter().any(|g| g.len() > 8), "groups span agents");
        }
        // Below the bound, or with one thread, there is no split.
        let small = window(100, 4, 3);
        assert!(pool.install(|| by_class(&small, one_pass)).is_none());
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        assert!(one
            .install(|| by_class(&window(300, 16, 1), one_pass))
            .is_none());
    }
}
