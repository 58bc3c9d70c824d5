use super::*;

/// A 4 m x 2 m box of height `h` whose KITTI `y` (the bottom, as the script reads it) is `y`,
/// as the KITTI readers give it: centre [x, z, y].
fn boxed(x: f64, y: f64, h: f64, id: u32, score: f64) -> Detection {
    Detection {
        center: [x, 0.0, y],
        size: [4.0, 2.0, h],
        id,
        score,
        ..v2x_protocol::fixtures::car(x, 0.0, 0.3)
    }
}

/// One object over three frames: track 5 twice, then track 6 (a switch); track 7 far away.
fn switching() -> Sequence {
    let gt = (0..3)
        .map(|f| vec![boxed(10.0 * f as f64, 0.0, 1.5, 1, 1.0)])
        .collect();
    let tracks = (0..3)
        .map(|f| {
            let (id, score) = if f < 2 { (5, 0.9) } else { (6, 0.3) };
            vec![
                boxed(10.0 * f as f64, 0.0, 1.5, id, score),
                boxed(100.0, 0.0, 1.5, 7, 0.8),
            ]
        })
        .collect();
    Sequence { gt, tracks }
}

#[test]
fn the_worked_case_gives_the_scripts_figures() {
    let m = evaluate(&[switching()]).unwrap();
    // Recall points (0.9, 1/40) and (0.3, 2/40). At 0.9 track 6 is dropped: 2 hits, 1 miss, no
    // switch, MOTA 2/3; at 0.3 every box: 3 hits, 1 switch, MOTA 2/3. sMOTA clips to 1 at both.
    let close = |a: f64, b: f64| assert!((a - b).abs() < 1e-12, "{a} against {b}");
    close(m.amota, (2.0 / 3.0 + 2.0 / 3.0) / 40.0);
    close(m.samota, 2.0 / 40.0);
    close(m.amotp, 2.0 / 40.0);
    // Best MOTA first reached at 0.9 (a tie later does not replace it).
    assert_eq!(m.threshold, 0.9);
    close(m.mota, 2.0 / 3.0);
    assert_eq!((m.tp, m.fp, m.fn_, m.ids, m.frag), (2, 0, 1, 0, 0));
    close(m.recall, 2.0 / 3.0);
    // Tracked 2 of 3 frames: partly tracked, neither mostly tracked nor mostly lost.
    assert_eq!((m.mt, m.ml), (0.0, 0.0));
}

#[test]
fn a_switch_and_a_fragment_are_counted_along_the_label_track() {
    // Track 5, a miss, track 6: one fragmentation; with no threshold above 0.3 dropping track
    // 6 first, the best MOTA is where both tracks stay.
    let mut s = switching();
    s.tracks[1].retain(|d| d.id == 7);
    for d in &mut s.tracks[2] {
        if d.id == 6 {
            d.score = 0.95;
        }
    }
    let m = evaluate(&[s]).unwrap();
    // [5, -1, 6]: no switch (a miss between), one fragmentation (the last frame's rule).
    assert_eq!((m.tp, m.ids, m.frag), (2, 0, 1));
}

#[test]
fn heights_span_the_scripts_bottom_up_interval() {
    // The label spans [-2, 0] (h 2 at y 0); the box of height 1 at y 0.5 spans [-0.5, 0.5]:
    // IoU 0.5 / (2 + 1 - 0.5) = 0.2 < 0.25, no match (centred heights would give 0.5).
    let s = Sequence {
        gt: vec![vec![boxed(0.0, 0.0, 2.0, 1, 1.0)]],
        tracks: vec![vec![boxed(0.0, 0.5, 1.0, 3, 0.9)]],
    };
    let m = evaluate(&[s]).unwrap();
    assert_eq!((m.tp, m.fn_), (0, 1));
    // At y 0 it spans [-1, 0]: IoU 1/2, a match with MOTP 0.5.
    let s = Sequence {
        gt: vec![vec![boxed(0.0, 0.0, 2.0, 1, 1.0)]],
        tracks: vec![vec![boxed(0.0, 0.0, 1.0, 3, 0.9)]],
    };
    let m = evaluate(&[s]).unwrap();
    assert_eq!(m.tp, 1);
    assert!((m.motp - 0.5).abs() < 1e-12);
}

#[test]
fn no_labels_no_figures() {
    assert_eq!(evaluate(&[]), None);
}

#[test]
fn the_scripts_iou_is_kept_where_it_is_no_iou() {
    // Its clip of two equal boxes turned by 1 rad meets coincident edges: the script scores the
    // pair 1.5382109980265983 (printed by its own `iou`), and so must we; unturned, exactly 1.
    let b = ScriptBox {
        x: -20.0,
        y: -1.0,
        z: -5.0,
        h: 1.5,
        w: 1.8,
        l: 4.5,
        ry: 1.0,
    };
    assert!(
        (script_iou(&b, &b) - 1.5382109980265983).abs() < 1e-9,
        "{}",
        script_iou(&b, &b)
    );
    let flat = ScriptBox { ry: 0.0, ..b };
    assert!((script_iou(&flat, &flat) - 1.0).abs() < 1e-12);
    // Shifted 0.3 m along the length and 0.2 m across: 4.2 x 1.6 over 2 x 8.1 less that.
    let shifted = ScriptBox {
        x: -19.7,
        z: -4.8,
        ..flat
    };
    let inter = 4.2 * 1.6;
    assert!((script_iou(&flat, &shifted) - inter / (16.2 - inter)).abs() < 1e-12);
    // Along the length only, the long edges coincide: the script says 1.7022518765637948.
    let along = ScriptBox { x: -19.7, ..flat };
    assert!(
        (script_iou(&flat, &along) - 1.7022518765637948).abs() < 1e-9,
        "{}",
        script_iou(&flat, &along)
    );
}

#[test]
fn counted_false_positives_charge_every_unmatched_box() {
    // As the script scores this layout, track 7 (far from the label, never matched) is free;
    // counted, it is 3 false positives wherever it stands.
    let close = |a: f64, b: f64| assert!((a - b).abs() < 1e-12, "{a} against {b}");
    let m = evaluate_with(&[switching()], FalsePositives::Counted).unwrap();
    // At 0.9 tracks 6 (0.3) and 7 (0.8) are dropped: MOTA 2/3; at 0.3 every box stands:
    // 3 hits, 1 switch, 3 false positives, MOTA 1 - 4/3.
    close(m.amota, (2.0 / 3.0 - 1.0 / 3.0) / 40.0);
    assert_eq!((m.threshold, m.fp), (0.9, 0));
    // One frame: an exact box and a far one, both 0.9.
    let s = Sequence {
        gt: vec![vec![boxed(0.0, 0.0, 1.5, 1, 1.0)]],
        tracks: vec![vec![
            boxed(0.0, 0.0, 1.5, 3, 0.9),
            boxed(50.0, 0.0, 1.5, 4, 0.9),
        ]],
    };
    let free = evaluate(std::slice::from_ref(&s)).unwrap();
    assert_eq!((free.fp, free.mota), (0, 1.0));
    let counted = evaluate_with(&[s], FalsePositives::Counted).unwrap();
    assert_eq!((counted.fp, counted.mota), (1, 0.0));
}
