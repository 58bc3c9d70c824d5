use super::*;
use v2x_protocol::Uncertainty;

fn car(x: f64, y: f64, z: f64, score: f64, std: f64) -> Detection {
    Detection {
        center: [x, y, z],
        score,
        std: Uncertainty::uniform(std, 0.2, 0.15),
        ..v2x_protocol::fixtures::car(x, y, std)
    }
}

#[test]
fn a_pairs_features_by_hand() {
    // The receiver's box at (29.8, 40) scoring 0.9 (std 0.5), the other car's 1 m along x and
    // 0.5 m higher scoring 0.6 (std 1.0), a fused box at (30, 40, 0.1), 0.3 m longer.
    let a = car(29.8, 40.0, 0.0, 0.9, 0.5);
    let b = car(30.8, 40.0, 0.5, 0.6, 1.0);
    let fused = Detection {
        size: [a.size[0] + 0.3, a.size[1], a.size[2]],
        ..car(30.0, 40.0, 0.1, 0.0, 0.4)
    };
    let x = features(&[(&b, false), (&a, true)], &fused);
    let (l9, l6) = ((0.9f64 / 0.1).ln(), (0.6f64 / 0.4).ln());
    // chi2: 0.2^2 / 0.25 + 0.8^2 / 1; range 50 m.
    let chi2 = 0.04 / 0.25 + 0.64;
    let want = [l9, l6, 1.0, 1.0, f64::ln_1p(chi2), 1.0, 1.0, 0.5, 0.3, l9];
    for (k, (g, w)) in x.iter().zip(want).enumerate() {
        assert!(
            (g - w).abs() < 1e-12,
            "{}: {g} against {w}",
            FEATURE_NAMES[k]
        );
    }
    // One box alone, not the receiver's: no second score, no spread; its score clamped.
    let lone = car(0.0, -25.0, 0.0, 1.0, 0.5);
    let x = features(&[(&lone, false)], &lone);
    let l99 = (0.99f64 / (1.0 - 0.99)).ln();
    assert_eq!(x, [l99, 0.0, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.0]);
}

/// A fixed sequence of uniforms in (0, 1) (a linear congruential generator).
fn uniforms(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
}

#[test]
fn a_fit_recovers_the_model_that_drew_the_labels() {
    let truth = ExistenceModel {
        bias: -1.0,
        weights: [1.5, 0.8, 1.0, -0.5, -0.7, -1.2, 0.9, -0.4, -0.6, 0.3],
    };
    let mut u = uniforms(7);
    let samples: Vec<(Features, bool)> = (0..40_000)
        .map(|_| {
            let multi = if u() < 0.5 { 1.0 } else { 0.0 };
            let s1 = 4.0 * u() - 2.0;
            let range = 2.0 * u();
            let x = [
                s1,
                multi * (4.0 * u() - 2.0),
                multi,
                if u() < 0.7 { 1.0 } else { 0.0 },
                3.0 * u() * multi,
                range,
                multi * range,
                2.0 * u(),
                2.0 * u(),
                multi * s1,
            ];
            let real = u() < truth.probability(&x);
            (x, real)
        })
        .collect();
    let fit = ExistenceModel::fit(&samples, 0.0).unwrap();
    // 40,000 samples: each weight within 0.15 (several standard errors).
    assert!((fit.bias - truth.bias).abs() < 0.15, "{fit:?}");
    for (k, (f, t)) in fit.weights.iter().zip(truth.weights).enumerate() {
        assert!(
            (f - t).abs() < 0.15,
            "{}: {f} against {t}",
            FEATURE_NAMES[k]
        );
    }
    // A penalty shrinks the weights.
    let shrunk = ExistenceModel::fit(&samples, 1e3).unwrap();
    let norm = |m: &ExistenceModel| m.weights.iter().map(|w| w * w).sum::<f64>();
    assert!(norm(&shrunk) < 0.5 * norm(&fit));
}

#[test]
fn a_fit_needs_both_kinds() {
    let x = [0.0; FEATURES];
    assert_eq!(
        ExistenceModel::fit(&[(x, true), (x, true)], 0.0),
        Err(ExistenceError::OneSided { real: 2, ghost: 0 })
    );
    assert_eq!(
        ExistenceModel::fit(&[], 0.0),
        Err(ExistenceError::OneSided { real: 0, ghost: 0 })
    );
}

#[test]
fn a_model_file_round_trips_and_names_what_is_wrong() {
    let m = DETECTOR_DEFAULT;
    let f = m.to_file([10, 20]);
    let text = serde_json::to_string(&f).unwrap();
    let back: ExistenceFile = serde_json::from_str(&text).unwrap();
    assert_eq!(ExistenceModel::try_from(back).unwrap(), m);
    let mut renamed = f.clone();
    renamed.weights[4].0 = "chi2".into();
    assert_eq!(
        ExistenceModel::try_from(renamed),
        Err(ExistenceError::Features {
            index: 4,
            found: "chi2".into(),
            expected: "ln1p_chi2"
        })
    );
    let mut short = f.clone();
    short.weights.pop();
    assert!(matches!(
        ExistenceModel::try_from(short),
        Err(ExistenceError::Features { index: 9, .. })
    ));
    let mut long = f.clone();
    long.weights.push(("extra".into(), 1.0));
    assert!(matches!(
        ExistenceModel::try_from(long),
        Err(ExistenceError::Features { index: 10, .. })
    ));
    let mut nan = f.clone();
    nan.weights[2].1 = f64::NAN;
    assert_eq!(
        ExistenceModel::try_from(nan),
        Err(ExistenceError::NotFinite("multi".into()))
    );
    let mut kind = f;
    kind.kind = "something else".into();
    assert!(matches!(
        ExistenceModel::try_from(kind),
        Err(ExistenceError::Kind(_))
    ));
}
