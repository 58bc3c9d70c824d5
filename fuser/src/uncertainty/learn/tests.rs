use super::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use v2x_protocol::Velocity;

fn car(x: f64, y: f64, std: f64) -> Detection {
    Detection {
        center: [x, y, 1.0],
        size: [4.6, 1.95, 1.75],
        yaw: 0.3,
        std: Uncertainty::uniform(std, std / 5.0, std / 10.0),
        ..v2x_protocol::fixtures::car(x, y, std)
    }
}

fn seen(t_us: u64, det: Detection) -> Seen {
    Seen { t_us, det }
}

#[test]
fn residuals_of_three_boxes_by_hand() {
    // t = 0, 0.1, 0.3 s: a = 2/3, b = 1/3; the line through x0 = 0 and x2 = 0.3 is at 0.1
    // at t1, so u = 0.9, n = sqrt(1 + 4/9 + 1/9) = sqrt(14) / 3, and with stds 0.5 everywhere
    // Var u = 0.25 * 14/9.
    let r = residuals(
        &seen(0, car(0.0, 5.0, 0.5)),
        &seen(100_000, car(1.0, 5.0, 0.5)),
        &seen(300_000, car(0.3, 5.0, 0.5)),
    );
    let n = 14f64.sqrt() / 3.0;
    let (e, w, s) = r[0][0];
    assert!((e - 0.9 / n).abs() < 1e-12, "{e}");
    assert!((w - 0.9 / (0.5 * n)).abs() < 1e-12, "{w}");
    assert_eq!(s, 0.5);
    // y lies on the line: no residual; no velocity: no velocity residual.
    assert!(r[0][1].0.abs() < 1e-12);
    assert!(r[4].is_empty());
    // Stds differing per box weigh in by (1): 0.5^2 + (2/3)^2 1^2 + (1/3)^2 2^2 = 0.25 + 8/9.
    let r = residuals(
        &seen(0, car(0.0, 5.0, 1.0)),
        &seen(100_000, car(1.0, 5.0, 0.5)),
        &seen(300_000, car(0.3, 5.0, 2.0)),
    );
    assert!((r[0][0].1 - 0.9 / (0.25f64 + 8.0 / 9.0).sqrt()).abs() < 1e-12);
}

#[test]
fn yaw_residuals_wrap_around_the_period() {
    // Headings of 179, -179 and 177 degrees at equal steps: the line through the ends is 179,
    // so the middle is 2 degrees off it, not 358.
    let deg = |d: f64| d.to_radians();
    let at = |yaw| Detection {
        yaw: deg(yaw),
        ..car(0.0, 0.0, 0.5)
    };
    let r = residuals(
        &seen(0, at(179.0)),
        &seen(100_000, at(-179.0)),
        &seen(200_000, at(177.0)),
    );
    let n = 1.5f64.sqrt();
    assert!((r[3][0].0.abs() - deg(3.0) / n).abs() < 1e-9, "{:?}", r[3]);
}

#[test]
fn medians_by_hand() {
    assert_eq!(median(&VecDeque::from(vec![3.0, 1.0, 2.0])), 2.0);
    assert_eq!(median(&VecDeque::from(vec![4.0, 1.0, 3.0, 2.0])), 2.5);
    assert_eq!(median(&VecDeque::new()), 0.0);
}

/// `n` cars on a grid 12 m apart, each row driving along x at its own speed.
struct Scene {
    cars: Vec<([f64; 2], f64)>,
}

impl Scene {
    fn new(n: usize) -> Self {
        Scene {
            cars: (0..n)
                .map(|i| {
                    let p = [(i % 8) as f64 * 12.0, (i / 8) as f64 * 12.0];
                    (p, (i / 8 % 5) as f64 * 2.0)
                })
                .collect(),
        }
    }

    /// An agent's boxes at `t` s: true noise `sigma` on the centre (a tenth on the velocity),
    /// stating `stated`.
    fn detect(&self, t: f64, sigma: f64, stated: f64, rng: &mut ChaCha8Rng) -> Vec<Detection> {
        let mut g = || -> f64 { StandardNormal.sample(rng) };
        self.cars
            .iter()
            .map(|&([x, y], v)| {
                let mut d = car(x + v * t + sigma * g(), y + sigma * g(), stated);
                d.center[2] += sigma * g();
                d.velocity = Some(Velocity {
                    v: [v + 0.1 * sigma * g(), 0.1 * sigma * g()],
                    std: [0.1 * stated; 2],
                });
                d
            })
            .collect()
    }
}

/// Learns over `frames` frames at 10 Hz from agents with (true, stated) centre stds.
fn learn(agents: &[(f64, f64)], frames: u64, seed: u64) -> Learner {
    let scene = Scene::new(40);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut l = Learner::new(LearnParams::default());
    for k in 0..frames {
        let t_us = 1_000_000 + k * 100_000;
        for (a, &(sigma, stated)) in agents.iter().enumerate() {
            let dets = scene.detect(t_us as f64 / 1e6, sigma, stated, &mut rng);
            l.observe(&format!("agent{a}"), t_us, &dets);
        }
    }
    l
}

#[test]
fn stds_stated_six_times_wrong_either_way_are_learned_and_flagged() {
    // agent0 states a sixth of its 1.2 m, agent1 six times its 0.25 m, agent2 is honest.
    let l = learn(&[(1.2, 0.2), (0.25, 1.5), (0.5, 0.5)], 40, 1);
    let r = l.report();
    for (agent, truth, rho, flagged) in [
        ("agent0", 1.2, 6.0, true),
        ("agent1", 0.25, 1.0 / 6.0, true),
        ("agent2", 0.5, 1.0, false),
    ] {
        let a = &r[agent];
        let xy = a.all.pos_xy.expect("learned");
        assert!(xy.samples >= 600, "{agent}: {xy:?}");
        assert!((xy.estimated / truth - 1.0).abs() < 0.1, "{agent}: {xy:?}");
        assert!((xy.ratio / rho - 1.0).abs() < 0.1, "{agent}: {xy:?}");
        assert_eq!(a.flagged, flagged, "{agent}");
        let z = a.all.pos_z.expect("learned");
        assert!((z.estimated / truth - 1.0).abs() < 0.15, "{agent}: {z:?}");
        let v = a.all.velocity.expect("learned");
        assert!(
            (v.estimated / (0.1 * truth) - 1.0).abs() < 0.15,
            "{agent}: {v:?}"
        );
        // The boxes are fused with the learned stds, not the stated ones.
        let mut d = vec![car(
            0.0,
            0.0,
            [0.2, 1.5, 0.5][agent[5..].parse::<usize>().unwrap()],
        )];
        l.correct(agent, &mut d);
        assert!(
            (d[0].std.pos[0] / truth - 1.0).abs() < 0.1,
            "{agent}: {:?}",
            d[0].std
        );
    }
}

#[test]
fn until_learned_stds_are_at_least_the_prior() {
    let l = Learner::new(LearnParams::default());
    let mut d = vec![car(0.0, 0.0, 0.5), car(0.0, 0.0, 5.0)];
    l.correct("rsu", &mut d);
    assert_eq!(d[0].std.pos, [3.0; 3]);
    assert_eq!(d[1].std.pos, [5.0; 3], "a larger stated std stands");
    assert_eq!(d[0].std.yaw, 60f64.to_radians());
    // Two frames give no residual: still the prior.
    let l = learn(&[(1.0, 0.5)], 2, 3);
    assert!(l.report()["agent0"].all.pos_xy.is_none());
}

#[test]
fn a_full_covariance_is_scaled_like_the_stds() {
    let l = learn(&[(1.0, 0.25)], 30, 4);
    let rho = l.report()["agent0"].ratio_xy.unwrap();
    let mut d = car(0.0, 0.0, 0.25);
    d.pos_cov = Some(Box::new([
        [0.0625, 0.01, 0.0],
        [0.01, 0.0625, 0.0],
        [0.0, 0.0, 0.0625],
    ]));
    let mut v = vec![d];
    l.correct("agent0", &mut v);
    let c = v[0].pos_cov.as_deref().unwrap();
    assert!((c[0][1] - 0.01 * rho * rho).abs() < 1e-12);
    assert!((c[0][0] - 0.0625 * rho * rho).abs() < 1e-12);
}

#[test]
fn an_agent_that_changes_is_followed() {
    let scene = Scene::new(40);
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut l = Learner::new(LearnParams::default());
    let mut t_us = 1_000_000;
    for (sigma, frames) in [(0.3, 30), (1.5, 30)] {
        for _ in 0..frames {
            l.observe(
                "a",
                t_us,
                &scene.detect(t_us as f64 / 1e6, sigma, 0.3, &mut rng),
            );
            t_us += 100_000;
        }
        let xy = l.report()["a"].all.pos_xy.unwrap();
        // 600 residuals, correlated in threes: about 6% of sampling error.
        assert!((xy.estimated / sigma - 1.0).abs() < 0.2, "{sigma}: {xy:?}");
    }
    l.forget("a");
    assert!(l.report().is_empty());
}

#[test]
fn stds_three_times_off_are_flagged_within_ten_seconds() {
    // At 10 Hz: the first frame after which each agent is flagged.
    let scene = Scene::new(40);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut l = Learner::new(LearnParams::default());
    let agents = [
        ("narrow", 1.5, 0.5),
        ("wide", 0.5, 1.5),
        ("honest", 1.0, 1.0),
    ];
    let mut first = [None; 3];
    for k in 0..100u64 {
        let t_us = k * 100_000;
        for (name, sigma, stated) in agents {
            l.observe(
                name,
                t_us,
                &scene.detect(t_us as f64 / 1e6, sigma, stated, &mut rng),
            );
        }
        let r = l.report();
        for (i, (name, ..)) in agents.iter().enumerate() {
            if r[*name].flagged && first[i].is_none() {
                first[i] = Some(k);
            }
        }
    }
    // Flagged after the first residuals are in: well within 100 frames, 10 s.
    assert!(first[0].is_some_and(|k| k < 10), "{first:?}");
    assert!(first[1].is_some_and(|k| k < 10), "{first:?}");
    assert_eq!(first[2], None, "an honest agent is never flagged");
    let r = l.report();
    let narrow = r["narrow"].ratio_xy.unwrap();
    assert!((narrow / 3.0 - 1.0).abs() < 0.15, "{narrow}");
    assert!((r["wide"].ratio_xy.unwrap() * 3.0 - 1.0).abs() < 0.15);
}
