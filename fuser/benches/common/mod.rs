//! The benches' scenes: nuScenes-like density (80 objects within 50 m, the area growing with the
//! count) and class mix, one noisy copy of the ground truth per agent.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use v2x_protocol::{wrap_angle, Detection, NoiseProfile, Uncertainty};

/// Ground truth of `n` objects, then one noisy copy per agent.
pub fn scene(n: usize, agents: usize, noise: NoiseProfile, seed: u64) -> Vec<Vec<Detection>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let radius = 50.0 * (n as f64 / 80.0).sqrt();
    let gt: Vec<Detection> = (0..n)
        .map(|i| {
            let class = v2x_protocol::fixtures::URBAN_MIX
                [rng.gen_range(0..v2x_protocol::fixtures::URBAN_MIX.len())];
            let r = radius * rng.gen::<f64>().sqrt();
            let a = rng.gen::<f64>() * std::f64::consts::TAU;
            Detection {
                class,
                center: [r * a.cos(), r * a.sin(), 1.0],
                size: class.typical_size(),
                yaw: rng.gen_range(-3.1..3.1),
                score: 0.8,
                std: noise.std(),
                pos_cov: None,
                velocity: None,
                id: i as u32,
            }
        })
        .collect();
    let s: Uncertainty = noise.std();
    (0..agents)
        .map(|_| {
            let mut g = || -> f64 { StandardNormal.sample(&mut rng) };
            gt.iter()
                .map(|d| {
                    let mut d = d.clone();
                    for k in 0..3 {
                        d.center[k] += s.pos[k] * g();
                        d.size[k] = (d.size[k] + s.size[k] * g()).max(0.05);
                    }
                    d.yaw = wrap_angle(d.yaw + s.yaw * g());
                    d
                })
                .collect()
        })
        .collect()
}
