//! scratch
use rand::{Rng, SeedableRng};
fn main() {
    let n_agents: usize = std::env::var("A").ok().and_then(|v| v.parse().ok()).unwrap_or(64);
    let n: usize = std::env::var("N").ok().and_then(|v| v.parse().ok()).unwrap_or(200);
    let reps: usize = std::env::var("R").ok().and_then(|v| v.parse().ok()).unwrap_or(50);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let radius = 50.0 * (n as f64 / 80.0).sqrt();
    let truth: Vec<(f64, f64)> = (0..n).map(|_| { let r = radius * rng.gen::<f64>().sqrt(); let a = rng.gen::<f64>() * 6.283; (r * a.cos(), r * a.sin()) }).collect();
    let agents: Vec<Vec<v2x_protocol::Detection>> = (0..n_agents).map(|_| truth.iter().map(|&(x, y)| {
        let nx: f64 = rng.gen::<f64>() - 0.5; let ny: f64 = rng.gen::<f64>() - 0.5;
        v2x_protocol::Detection::car(x + 0.6 * nx, y + 0.6 * ny, 0.3)
    }).collect()).collect();
    let m: v2x_fuser::Method = std::env::var("M").unwrap_or("csba-wls+".into()).parse().unwrap();
    let mut ts = vec![];
    let mut out = 0;
    for _ in 0..reps { let t = std::time::Instant::now(); out = m.fuse(&agents).len(); ts.push(t.elapsed().as_secs_f64() * 1e3); }
    ts.sort_by(f64::total_cmp);
    println!("{} agents x {n}: median {:.3} ms p90 {:.3} ms, {out} fused", n_agents, ts[reps / 2], ts[reps * 9 / 10]);
}
