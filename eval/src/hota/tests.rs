use super::*;

/// `eval/fixtures/hota_case.json`.
fn case() -> Vec<Vec<Frame>> {
    let text = include_str!("../../fixtures/hota_case.json");
    let v: serde_json::Value = serde_json::from_str(text).unwrap();
    let ids = |v: &serde_json::Value| -> Vec<u32> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_u64().unwrap() as u32)
            .collect()
    };
    v["sequences"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| {
            s.as_array()
                .unwrap()
                .iter()
                .map(|f| {
                    let tracks = ids(&f["tracks"]);
                    Frame {
                        gt: ids(&f["gt"]),
                        similarity: f["similarity"]
                            .as_array()
                            .unwrap()
                            .iter()
                            .map(|r| {
                                let mut row: Vec<f64> = r
                                    .as_array()
                                    .unwrap()
                                    .iter()
                                    .map(|x| x.as_f64().unwrap())
                                    .collect();
                                row.resize(tracks.len(), 0.0);
                                row
                            })
                            .collect(),
                        tracks,
                    }
                })
                .collect()
        })
        .collect()
}

#[test]
fn the_shared_case_scores_as_trackeval_scores_it() {
    // `python eval/fixtures/hota_trackeval.py` (trackeval 1.3.0), to the digits it prints.
    let m = hota(&case());
    let want = [
        0.434132887721059,
        0.384368522620749,
        0.498556998556998,
        0.522556390977444,
        0.522556390977444,
        0.559649122807018,
        0.756085288980026,
        0.779343814080656,
    ];
    let got = [
        m.hota, m.deta, m.assa, m.detre, m.detpr, m.assre, m.asspr, m.loca,
    ];
    for (k, (g, w)) in got.iter().zip(want).enumerate() {
        assert!((g - w).abs() < 1e-12, "field {k}: {g} against {w}");
    }
}

#[test]
fn perfect_tracks_score_one_and_a_swap_halves_association() {
    let frame = |tracks: [u32; 2]| Frame {
        gt: vec![1, 2],
        tracks: tracks.to_vec(),
        similarity: vec![vec![1.0, 0.0], vec![0.0, 1.0]],
    };
    let perfect = hota(&[vec![frame([7, 8]); 4]]);
    assert_eq!(
        (perfect.hota, perfect.deta, perfect.assa, perfect.loca),
        (1.0, 1.0, 1.0, 1.0)
    );
    // The tracks trade objects halfway: every box still found, each pair matched 2 of 4
    // frames: AssA = 2 / (4 + 4 - 2) = 1/3.
    let swapped = hota(&[vec![
        frame([7, 8]),
        frame([7, 8]),
        frame([8, 7]),
        frame([8, 7]),
    ]]);
    assert_eq!(swapped.deta, 1.0);
    assert!((swapped.assa - 1.0 / 3.0).abs() < 1e-12, "{swapped:?}");
    assert!((swapped.hota - (1.0f64 / 3.0).sqrt()).abs() < 1e-12);
    // A box of similarity 0.5 is found for alphas up to 0.5 (10 of 19).
    let half = hota(&[vec![Frame {
        gt: vec![1],
        tracks: vec![7],
        similarity: vec![vec![0.5]],
    }]]);
    assert!((half.deta - 10.0 / 19.0).abs() < 1e-12, "{half:?}");
    // Nothing to score: no detection, no association (LocA 1 by TrackEval's convention).
    let none = hota(&[]);
    assert_eq!(
        (none.hota, none.deta, none.assa, none.loca),
        (0.0, 0.0, 0.0, 1.0)
    );
}
