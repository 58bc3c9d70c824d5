use super::*;
use proptest::prelude::*;
use v2x_protocol::Uncertainty;

fn det(
    center: [f64; 3],
    size: [f64; 3],
    yaw: f64,
    pos_std: f64,
    size_std: f64,
    yaw_std: f64,
) -> Detection {
    Detection {
        center,
        size,
        yaw,
        std: Uncertainty {
            pos: [pos_std; 3],
            size: [size_std; 3],
            yaw: yaw_std,
        },
        id: 0,
        ..v2x_protocol::fixtures::car(0.0, 0.0, pos_std)
    }
}

fn close(a: f64, b: f64) {
    assert!((a - b).abs() < 1e-9, "{a} vs {b}");
}

#[test]
fn dimension_score_hand_computed() {
    // V_a = 8, sigma = 8 sqrt(3 * 0.05^2); V_b = 4, sigma = 4 sqrt(0.05^2 + 0.05^2 + 0.1^2)
    // r = 2, sigma_r = 2 sqrt(0.0075 + 0.015) = 0.3; Z_r = 3.33, Z_inv = -1.67 -> DS = exp(-25/18)
    let a = det([0.0; 3], [2.0, 2.0, 2.0], 0.0, 1.0, 0.1, 0.1);
    let b = det([0.0; 3], [2.0, 2.0, 1.0], 0.0, 1.0, 0.1, 0.1);
    close(dimension_score(&a, &b), (-25.0f64 / 18.0).exp());
    // The printed form is not symmetric: with r = 1/2, sigma_r = 0.075, Z_r = -6.67, Z_inv = 13.3
    close(dimension_score(&b, &a), (-200.0f64 / 9.0).exp());
    // The log-ratio form is: Z = ln 2 / 0.15
    let z = 2f64.ln() / 0.15;
    close(dimension_score_log(&a, &b), (-z * z / 2.0).exp());
    close(dimension_score_log(&b, &a), (-z * z / 2.0).exp());
    close(dimension_score(&a, &a), 1.0);
}

#[test]
fn centre_score_hand_computed() {
    let a = det([0.0; 3], [4.0, 2.0, 1.5], 0.0, 1.0, 0.1, 0.1);
    let b = det([3.0, 4.0, 0.0], [4.0, 2.0, 1.5], 0.0, 1.0, 0.1, 0.1);
    // S = 2 I -> d_M = 5 / sqrt(2); lambda = 6 x 1
    close(mahalanobis(&a, &b), 5.0 / 2f64.sqrt());
    close(lambda_max(CsbaParams::PAPER.gate, &a, &b), 6.0);
    close(
        centre_score(5.0 / 2f64.sqrt(), 6.0),
        1.0 - 5.0 / (6.0 * 2f64.sqrt()),
    );
    close(centre_score(7.0, 6.0), 0.0);
    // the noisier detection sets lambda
    let c = det([0.0; 3], [4.0, 2.0, 1.5], 0.0, 3.0, 0.1, 0.1);
    close(lambda_max(CsbaParams::PAPER.gate, &a, &c), 18.0);
    close(lambda_max(CsbaParams::PLUS.gate, &a, &c), MAHALANOBIS_GATE);
}

#[test]
fn mahalanobis_with_full_covariance() {
    // Sa + Sb = [[2, 1, 0], [1, 2, 0], [0, 0, 2]], dp = (1, 1, 0): inv applied gives 2/3
    let mut a = det([1.0, 1.0, 0.0], [4.0, 2.0, 1.5], 0.0, 1.0, 0.1, 0.1);
    a.pos_cov = Some(Box::new([
        [1.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ]));
    let b = det([0.0; 3], [4.0, 2.0, 1.5], 0.0, 1.0, 0.1, 0.1);
    close(mahalanobis(&a, &b), (2.0f64 / 3.0).sqrt());
}

#[test]
fn orientation_scores_hand_computed() {
    // paper form: alpha = yaw / sigma
    let a = det([0.0; 3], [4.0, 2.0, 1.5], 0.5, 1.0, 0.1, 0.25);
    let b = det([0.0; 3], [4.0, 2.0, 1.5], 0.2, 1.0, 0.1, 0.1);
    close(orientation_score(Orientation::Paper, &a, &b), 1.0); // alpha 2 and 2
    let c = det(
        [0.0; 3],
        [4.0, 2.0, 1.5],
        std::f64::consts::FRAC_PI_2,
        1.0,
        0.1,
        1.0,
    );
    let d = det([0.0; 3], [4.0, 2.0, 1.5], 0.0, 1.0, 0.1, 1.0);
    close(orientation_score(Orientation::Paper, &c, &d), 0.5);
    // wrapped: 179 and -179 deg are 2 deg apart
    let s = 2f64.to_radians();
    let e = det([0.0; 3], [4.0, 2.0, 1.5], 179f64.to_radians(), 1.0, 0.1, s);
    let f = det([0.0; 3], [4.0, 2.0, 1.5], -179f64.to_radians(), 1.0, 0.1, s);
    close(
        orientation_score(Orientation::Wrapped, &e, &f),
        (-0.25f64).exp(),
    );
    // barriers have period pi
    let mut g = e.clone();
    let mut h = f.clone();
    g.class = Class::Barrier;
    h.class = Class::Barrier;
    g.yaw = 0.0;
    h.yaw = std::f64::consts::PI - s;
    close(
        orientation_score(Orientation::Wrapped, &g, &h),
        (-0.25f64).exp(),
    );
}

#[test]
fn log_likelihood_cost_hand_computed() {
    // Gaussian centre score exp(-d^2/2) with d = 1, OS = DS = 1: C = 0.5 * 0.5 / 1.0
    close(log_cost([0.2, 0.5, 0.3], 1.0, (-0.5f64).exp(), 1.0), 0.25);
    let a = det([0.0; 3], [4.0, 2.0, 1.5], 0.0, 1.0, 0.1, 0.1);
    let b = det([1.0, 1.0, 0.0], [4.0, 2.0, 1.5], 0.0, 1.0, 0.1, 0.1);
    // d_M^2 = 2 / 2 = 1 -> C = 0.5 * 0.5
    close(pair_cost(&CsbaParams::PLUS, &a, &b).unwrap(), 0.25);
}

#[test]
fn weighted_cost() {
    close(cost([0.2, 0.5, 0.3], 0.5, 0.5, 0.5), 0.5);
    close(cost([0.2, 0.5, 0.3], 1.0, 0.4, 0.0), 0.6);
    close(cost([1.0, 1.0, 2.0], 0.0, 1.0, 1.0), 0.25);
}

#[test]
fn gate_rejects_other_classes_and_far_pairs() {
    let a = det([0.0; 3], [4.0, 2.0, 1.5], 0.0, 0.5, 0.1, 0.1);
    let mut b = a.clone();
    b.class = Class::Truck;
    assert_eq!(pair_cost(&CsbaParams::PAPER, &a, &b), None);
    let far = det([2.2, 0.0, 0.0], [4.0, 2.0, 1.5], 0.0, 0.5, 0.1, 0.1);
    // d_M = 2.2 / sqrt(0.5) = 3.11 > lambda = 3
    assert_eq!(pair_cost(&CsbaParams::PAPER, &a, &far), None);
    assert!(pair_cost(&CsbaParams::PLUS, &a, &far).is_some());
    // d_M = 4.3 / sqrt(0.5) = 6.08 > 6
    let farther = det([4.3, 0.0, 0.0], [4.0, 2.0, 1.5], 0.0, 0.5, 0.1, 0.1);
    assert_eq!(pair_cost(&CsbaParams::PLUS, &a, &farther), None);
}

/// `d` moving at `v` (m/s) with a std of `std` per axis.
fn moving(mut d: Detection, v: [f64; 2], std: f64) -> Detection {
    d.velocity = Some(v2x_protocol::Velocity { v, std: [std; 2] });
    d
}

#[test]
fn velocity_distance_hand_computed() {
    let a = det([0.0; 3], [4.0, 2.0, 1.5], 0.0, 0.5, 0.1, 0.1);
    // (1 - 0)^2 / (0.25 + 0.25) + (0 - 1)^2 / 0.5 = 4
    let (va, vb) = (
        moving(a.clone(), [1.0, 0.0], 0.5),
        moving(a.clone(), [0.0, 1.0], 0.5),
    );
    close(velocity_distance2(&va, &vb).unwrap(), 4.0);
    assert_eq!(velocity_distance2(&va, &a), None);
}

#[test]
fn velocity_gate_rejects_pairs_moving_apart_and_only_them() {
    let gated = CsbaParams {
        velocity_gate: Some(CHI2_2_999),
        ..CsbaParams::PLUS
    };
    let a = moving(
        det([0.0; 3], [4.0, 2.0, 1.5], 0.0, 0.5, 0.1, 0.1),
        [0.0, 0.0],
        1.0,
    );
    // dv^2 = v^2 / 2: 5.3^2 / 2 = 14.05 beyond 13.816, 5.2^2 / 2 = 13.52 inside
    let apart = moving(a.clone(), [5.3, 0.0], 1.0);
    let inside = moving(a.clone(), [5.2, 0.0], 1.0);
    assert_eq!(pair_cost(&gated, &a, &apart), None);
    assert!(pair_cost(&CsbaParams::PLUS, &a, &apart).is_some());
    // Inside the gate the velocity does not change the cost.
    assert_eq!(
        pair_cost(&gated, &a, &inside),
        pair_cost(&CsbaParams::PLUS, &a, &inside)
    );
    // A box without a velocity is not compared.
    let still = det([0.0; 3], [4.0, 2.0, 1.5], 0.0, 0.5, 0.1, 0.1);
    assert!(pair_cost(&gated, &apart, &still).is_some());
}

fn e(a: usize, b: usize, cost: f64) -> Edge {
    Edge::new(a, b, cost)
}

#[test]
fn assignment_2x2_known_optimum() {
    let edges = [e(0, 0, 0.1), e(0, 1, 0.2), e(1, 0, 0.2), e(1, 1, 0.9)];
    assert_eq!(assign(2, 2, &edges), vec![(0, 1), (1, 0)]);
}

#[test]
fn assignment_3x3_known_optimum() {
    // [[4,1,3],[2,0,5],[3,2,2]] / 10: optimum 0.5 with (0,1), (1,0), (2,2)
    let m = [[0.4, 0.1, 0.3], [0.2, 0.0, 0.5], [0.3, 0.2, 0.2]];
    let edges: Vec<Edge> = (0..3)
        .flat_map(|i| (0..3).map(move |j| (i, j)))
        .map(|(i, j)| e(i, j, m[i][j]))
        .collect();
    assert_eq!(assign(3, 3, &edges), vec![(0, 1), (1, 0), (2, 2)]);
}

#[test]
fn assignment_prefers_more_matches_and_keeps_components_apart() {
    // a1 could take b0 cheaply, but then a0 would stay unmatched.
    let edges = [e(0, 0, 0.9), e(1, 0, 0.1), e(1, 1, 0.8), e(2, 3, 0.3)];
    assert_eq!(assign(3, 4, &edges), vec![(0, 0), (1, 1), (2, 3)]);
    assert_eq!(assign(5, 5, &[]), vec![]);
}

#[test]
fn negative_costs_still_give_the_largest_matching() {
    // a0-b0 alone saves 10; a0-b1 + a1-b0 save only 2 together, but match two pairs.
    let edges = [e(0, 0, -10.0), e(0, 1, -1.0), e(1, 0, -1.0)];
    assert_eq!(assign(2, 2, &edges), vec![(0, 1), (1, 0)]);
    assert_eq!(assign_dense(2, 2, &edges), vec![(0, 1), (1, 0)]);
    // beyond the exact limit on the whole (3 x 3 > 4), components built, none beyond it: the same
    let with_other = [edges.as_slice(), &[e(2, 2, -0.5)]].concat();
    let mut kept = Kept::default();
    assert_eq!(
        assign_with(&mut kept, 3, 3, &with_other, 4),
        vec![(0, 1), (1, 0), (2, 2)]
    );
}

#[test]
fn a_component_beyond_the_limit_is_matched_greedily_and_the_others_exactly() {
    // Component 1: a0, a1 x b0, b1 (4 possible pairs). Greedy takes (0, 0) at 0.1 and is left
    // with (1, 1) at 0.9 (total 1.0); the optimum is (0, 1) + (1, 0) at 0.3 + 0.3.
    // Component 2: a2 x b2, b3 (2 pairs), the same trap one row smaller.
    let edges = [
        e(0, 0, 0.1),
        e(0, 1, 0.3),
        e(1, 0, 0.3),
        e(1, 1, 0.9),
        e(2, 2, 0.2),
        e(2, 3, 0.4),
    ];
    let mut kept = Kept::default();
    // limit 3: only component 1 (2 x 2 = 4 pairs) is beyond it
    assert_eq!(
        assign_with(&mut kept, 3, 4, &edges, 3),
        vec![(0, 0), (1, 1), (2, 2)]
    );
    // limit 1: both are greedy; component 2 is the same either way
    assert_eq!(
        assign_with(&mut kept, 3, 4, &edges, 1),
        vec![(0, 0), (1, 1), (2, 2)]
    );
    // within the limit, or as one whole: exact
    let exact = vec![(0, 1), (1, 0), (2, 2)];
    assert_eq!(assign_with(&mut kept, 3, 4, &edges, 4), exact);
    assert_eq!(assign_with(&mut kept, 3, 4, &edges, 12), exact);
    assert_eq!(assign(3, 4, &edges), exact);
}

#[test]
fn associate_matches_noisy_copies() {
    let a: Vec<Detection> = (0..20)
        .map(|i| {
            det(
                [i as f64 * 5.0, (i % 3) as f64 * 4.0, 0.0],
                [4.0, 2.0, 1.5],
                0.1 * i as f64,
                0.5,
                0.1,
                0.1,
            )
        })
        .collect();
    // b: the same objects in reverse order, shifted 0.3 m
    let b: Vec<Detection> = a
        .iter()
        .rev()
        .map(|d| {
            let mut d = d.clone();
            d.center[0] += 0.3;
            d
        })
        .collect();
    for p in [CsbaParams::PAPER, CsbaParams::PLUS] {
        let pairs = associate(&p, &a, &b);
        assert_eq!(pairs.len(), 20);
        for (i, j) in pairs {
            assert_eq!(j, 19 - i);
        }
    }
}

/// A crowded scene: 40 cars in a 30 m square with 1.5 m position noise, so that most boxes
/// have several eligible partners and the solve has conflicts to settle; b is a noisy copy of
/// a in another order.
fn crowded(seed: u64) -> (Vec<Detection>, Vec<Detection>) {
    let mut state = seed;
    let mut uniform = move || {
        // xorshift64: a fixed sequence, no crate needed
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let a: Vec<Detection> = (0..40)
        .map(|_| {
            det(
                [30.0 * uniform(), 30.0 * uniform(), 0.0],
                [4.0 + uniform(), 2.0, 1.5],
                uniform() * 6.0 - 3.0,
                1.5,
                0.5,
                0.5,
            )
        })
        .collect();
    let b = a
        .iter()
        .rev()
        .map(|d| {
            let mut d = d.clone();
            d.center[0] += 3.0 * (uniform() - 0.5);
            d.center[1] += 3.0 * (uniform() - 0.5);
            d.yaw = wrap_angle(d.yaw + uniform() - 0.5);
            d
        })
        .collect();
    (a, b)
}

#[test]
fn copies_far_apart_associate_as_each_copy_alone() {
    // Four copies of a crowded scene, 1 km apart, interleaved in both lists (copy k of box i
    // at index 4 i + k): each copy's pairs are those of the scene alone.
    const COPIES: usize = 4;
    let (a, b) = crowded(7);
    let copies = |list: &[Detection]| -> Vec<Detection> {
        list.iter()
            .flat_map(|d| {
                (0..COPIES).map(move |k| {
                    let mut d = d.clone();
                    d.center[0] += 1000.0 * k as f64;
                    d
                })
            })
            .collect()
    };
    let (many_a, many_b) = (copies(&a), copies(&b));
    for p in [CsbaParams::PAPER, CsbaParams::PLUS] {
        let alone = associate(&p, &a, &b);
        // crowded enough that the scene is no trivial one-to-one matching
        assert!(eligible_pairs(&p, &a, &b).len() > 3 * a.len(), "{p:?}");
        assert!(alone.len() >= 30, "{p:?}: {}", alone.len());
        let mut expected: Vec<(usize, usize)> = alone
            .iter()
            .flat_map(|&(i, j)| (0..COPIES).map(move |k| (COPIES * i + k, COPIES * j + k)))
            .collect();
        expected.sort_unstable();
        assert_eq!(associate(&p, &many_a, &many_b), expected, "{p:?}");
    }
}

/// Brute force: among all matchings using allowed edges, the largest, then the cheapest.
fn brute(nr: usize, nc: usize, m: &[Option<f64>]) -> (usize, f64) {
    fn rec(
        r: usize,
        nr: usize,
        nc: usize,
        m: &[Option<f64>],
        used: &mut Vec<bool>,
    ) -> (usize, f64) {
        if r == nr {
            return (0, 0.0);
        }
        let mut best = rec(r + 1, nr, nc, m, used);
        for c in 0..nc {
            if let (false, Some(x)) = (used[c], m[r * nc + c]) {
                used[c] = true;
                let (k, s) = rec(r + 1, nr, nc, m, used);
                used[c] = false;
                let cand = (k + 1, s + x);
                if cand.0 > best.0 || (cand.0 == best.0 && cand.1 < best.1 - 1e-12) {
                    best = cand;
                }
            }
        }
        best
    }
    rec(0, nr, nc, m, &mut vec![false; nc])
}

proptest! {
    #[test]
    fn assignment_is_optimal(nr in 1usize..6, nc in 1usize..6, seed in prop::collection::vec((0.0f64..1.0, 0.0f64..1.0), 36)) {
        let m: Vec<Option<f64>> = (0..nr * nc).map(|k| (seed[k].1 < 0.75).then_some(seed[k].0)).collect();
        let edges: Vec<Edge> = (0..nr * nc).filter_map(|k| m[k].map(|c| e(k / nc, k % nc, c))).collect();
        let pairs = assign(nr, nc, &edges);
        let total: f64 = pairs.iter().map(|&(i, j)| m[i * nc + j].unwrap()).sum();
        let (k, best) = brute(nr, nc, &m);
        prop_assert_eq!(pairs.len(), k);
        prop_assert!((total - best).abs() < 1e-9, "{} vs {}", total, best);
        // a valid matching
        let mut rows: Vec<_> = pairs.iter().map(|p| p.0).collect();
        let mut cols: Vec<_> = pairs.iter().map(|p| p.1).collect();
        rows.dedup(); cols.sort(); cols.dedup();
        prop_assert_eq!(rows.len(), pairs.len());
        prop_assert_eq!(cols.len(), pairs.len());
    }

    #[test]
    fn sweep_finds_every_eligible_pair(pts in prop::collection::vec((-30.0f64..30.0, -30.0f64..30.0, 0.2f64..3.0, 0usize..2), 1..30)) {
        let dets: Vec<Detection> = pts.iter().map(|&(x, y, s, c)| {
            let mut d = det([x, y, 0.0], [4.0, 2.0, 1.5], 0.0, s, 0.1, 0.2);
            d.class = [Class::Car, Class::Pedestrian][c];
            d
        }).collect();
        let (a, b) = dets.split_at(dets.len() / 2);
        for p in [CsbaParams::PAPER, CsbaParams::PLUS] {
            // the same pairs at the same costs, to the bit
            prop_assert_eq!(grid_pairs(&p, a, b), every_pair(&p, a, b));
        }
        // The log-product cost, taken from the scores' exponents, is the scores' formula.
        for da in a {
            for db in b {
                let Some(c) = pair_cost(&CsbaParams::PLUS, da, db) else { continue };
                let d_m = mahalanobis(da, db);
                let by_scores = log_cost(
                    [0.2, 0.5, 0.3],
                    dimension_score_log(da, db),
                    (-d_m * d_m / 2.0).exp(),
                    orientation_score(Orientation::Wrapped, da, db),
                );
                prop_assert!((c - by_scores).abs() < 1e-9 * (1.0 + c), "{} vs {}", c, by_scores);
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Over a wide scene of many classes (many cells, cells widened to the budget, boxes on
    /// cell borders), the grid finds exactly the pairs a scan of every pair finds.
    #[test]
    fn the_grid_finds_every_pair_of_a_wide_scene(
        pts in prop::collection::vec((-200.0f64..200.0, -200.0f64..200.0, 0.1f64..4.0, 0usize..10, any::<bool>()), 2..120),
    ) {
        let dets: Vec<Detection> = pts.iter().map(|&(x, y, s, c, snap)| {
            // snapped centres sit exactly on multiples of 5 m, where cell borders fall
            let (x, y) = if snap { ((x / 5.0).round() * 5.0, (y / 5.0).round() * 5.0) } else { (x, y) };
            let mut d = det([x, y, 0.0], [4.0, 2.0, 1.5], 0.3 * c as f64, s, 0.1, 0.2);
            d.class = Class::ALL[c];
            d
        }).collect();
        let (a, b) = dets.split_at(dets.len() / 3);
        for p in [CsbaParams::PAPER, CsbaParams::PLUS] {
            prop_assert_eq!(grid_pairs(&p, a, b), every_pair(&p, a, b));
        }
    }
}

/// [`eligible_pairs`] as sorted (a, b, cost bits).
fn grid_pairs(p: &CsbaParams, a: &[Detection], b: &[Detection]) -> Vec<(usize, usize, u64)> {
    let mut pairs: Vec<_> = eligible_pairs(p, a, b)
        .iter()
        .map(|e| (e.ia(), e.ib(), e.cost.to_bits()))
        .collect();
    pairs.sort();
    pairs
}

/// Every pair [`pair_cost`] admits, found by trying them all, as sorted (a, b, cost bits).
fn every_pair(p: &CsbaParams, a: &[Detection], b: &[Detection]) -> Vec<(usize, usize, u64)> {
    let mut pairs = Vec::new();
    for (i, da) in a.iter().enumerate() {
        for (j, db) in b.iter().enumerate() {
            if let Some(c) = pair_cost(p, da, db) {
                pairs.push((i, j, c.to_bits()));
            }
        }
    }
    pairs
}

/// Total cost of a set of pairs under the edges.
fn total(edges: &[Edge], pairs: &[(usize, usize)]) -> f64 {
    pairs
        .iter()
        .map(|&(a, b)| {
            edges
                .iter()
                .find(|e| e.ia() == a && e.ib() == b)
                .expect("a pair is an edge")
                .cost
        })
        .sum()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// The sparse solve reaches the dense solve's optimum (size, then cost) on random sparse
    /// and dense instances up to 60 x 60, ties and rectangular shapes included.
    #[test]
    fn sparse_solve_equals_the_dense_solve(
        nr in 1usize..60,
        nc in 1usize..60,
        density in 0.01f64..1.0,
        coarse in any::<bool>(),
        shuffled in any::<bool>(),
        negative in any::<bool>(),
        seed in any::<u64>(),
    ) {
        use rand::{seq::SliceRandom, Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut edges = Vec::new();
        for a in 0..nr {
            for b in 0..nc {
                if rng.gen::<f64>() < density {
                    // coarse costs make many ties
                    let c: f64 = if coarse { rng.gen_range(0..4) as f64 } else { rng.gen_range(0.0..5.0) };
                    // negative costs too, as the tracker's log-likelihoods can be
                    edges.push(e(a, b, if negative { c - 3.0 } else { c }));
                }
            }
        }
        // edges in any order, not only grouped by a as the eligible pairs come
        if shuffled {
            edges.shuffle(&mut rng);
        }
        let sparse = assign(nr, nc, &edges);
        let dense = assign_dense(nr, nc, &edges);
        prop_assert_eq!(sparse.len(), dense.len());
        let (ts, td) = (total(&edges, &sparse), total(&edges, &dense));
        prop_assert!((ts - td).abs() < 1e-9, "sparse {} vs dense {}", ts, td);
        // Past the limit on the whole (components built, each row its own unmatched cost) the
        // optimum is the same while no component is beyond the limit.
        let mut kept = Kept::default();
        let split = assign_with(&mut kept, nr, nc, &edges, nr * nc - 1);
        if !kept.components.any_piled() {
            prop_assert_eq!(split.len(), dense.len());
            let tc = total(&edges, &split);
            prop_assert!((tc - td).abs() < 1e-9, "components {} vs dense {}", tc, td);
        }
        let mut rows: Vec<_> = sparse.iter().map(|p| p.0).collect();
        let mut cols: Vec<_> = sparse.iter().map(|p| p.1).collect();
        rows.dedup(); cols.sort(); cols.dedup();
        prop_assert_eq!(rows.len(), sparse.len());
        prop_assert_eq!(cols.len(), sparse.len());
    }
}

#[test]
fn edges_without_a_finite_cost_are_not_eligible() {
    let edges = [
        e(0, 0, f64::INFINITY),
        e(0, 1, 0.5),
        e(1, 0, f64::NAN),
        e(1, 1, 0.2),
        e(2, 2, f64::NEG_INFINITY),
    ];
    // Of the finite pairs (0, 1) and (1, 1), which share column 1, the cheaper.
    assert_eq!(assign(3, 3, &edges), vec![(1, 1)]);
    assert_eq!(assign(3, 3, &[e(0, 0, f64::INFINITY)]), vec![]);
}

#[test]
fn the_bounds_are_counted_on_the_thread_that_met_them() {
    // One box against 200 co-located ones: its candidates are cut to the cheapest 128, once.
    let one = vec![det([0.0; 3], [4.0, 2.0, 1.5], 0.0, 0.5, 0.1, 0.1)];
    let pile: Vec<Detection> = (0..200)
        .map(|i| {
            det(
                [0.001 * i as f64, 0.0, 0.0],
                [4.0, 2.0, 1.5],
                0.0,
                0.5,
                0.1,
                0.1,
            )
        })
        .collect();
    let here = bounds_applied();
    let there = std::thread::spawn(move || {
        let before = bounds_applied();
        let edges = eligible_pairs(&CsbaParams::default(), &one, &pile);
        let after = bounds_applied();
        (edges.len(), after.0 - before.0)
    })
    .join()
    .unwrap();
    assert_eq!(there, (MAX_CANDIDATES, 1));
    // Another thread's fusion (another node's) leaves this thread's figures as they were.
    assert_eq!(bounds_applied(), here);
}
