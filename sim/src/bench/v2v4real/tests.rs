use super::*;
use std::path::Path;
use v2x_protocol::Uncertainty;
use v2x_truth::v2v4real::{load, Split};

fn fixture() -> V2v4real {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../truth/fixtures/v2v4real/AB3DMOT");
    load(&root, Split::Train, Uncertainty::uniform(0.5, 0.1, 0.1)).unwrap()
}

#[test]
fn each_row_scores_as_worked_by_hand() {
    let d = fixture();
    let methods = ["csba-wls+".parse().unwrap()];
    let rows = run(&d, &sources(&d, &methods));
    let names: Vec<&str> = rows.iter().map(|r| r.method.as_str()).collect();
    assert_eq!(
        names,
        [
            "ego alone",
            "car 1 alone",
            "dataset late fusion",
            "late fusion rule (BEV NMS 0.15)",
            "late fusion rule, score >= 0.4",
            "csba-wls+"
        ]
    );
    let bev = |k: usize| rows[k].ap.ap_bev["0.50"];
    let close = |got: f64, want: f64| assert!((got - want).abs() < 1e-12, "{got} against {want}");
    // Eight labelled cars over five frames. The ego car: hit, false | hit | hit hit | hit | -.
    close(bev(0), 1.0 / 8.0 + 4.0 / 8.0 * 5.0 / 6.0);
    // Car 1: four hits and nothing else.
    close(bev(1), 0.5);
    // The reference holds frame 0's two cars only.
    close(bev(2), 0.25);
    // Pooled and suppressed: every car found, the ego car's false box the only miss.
    close(bev(3), 2.0 / 8.0 + 6.0 / 8.0 * 8.0 / 9.0);
    assert_eq!(rows[3].ap.predictions, 9);
    // The tail below 0.4 dropped: the false box goes, and so does the last frame's lone 0.3 car.
    close(bev(4), 7.0 / 8.0);
    // csba-wls+ on a detector's boxes: the ego car's and car 1's first car fuse; the false
    // box 42 m out (0.25, its chance 0.10) falls below 0.2, the lone 0.3 car near the ego car
    // (its chance 0.22) stays: every car found, nothing else.
    close(bev(5), 1.0);
    assert_eq!((rows[4].ap.predictions, rows[5].ap.predictions), (7, 8));
    assert_eq!(rows[5].ap.global.bev["0.50"], 1.0);
    // Bytes: a fusion sends both cars' frames; a reference, none of the project's.
    let b = |k: usize| rows[k].bytes_per_frame;
    assert!(b(0).unwrap() > 0.0 && b(1).unwrap() > 0.0);
    assert!((b(5).unwrap() - b(0).unwrap() - b(1).unwrap()).abs() < 1e-9);
    assert_eq!(b(2), None);
    let cpm = |k: usize| rows[k].cpm_bytes_per_frame;
    assert!((cpm(5).unwrap() - cpm(0).unwrap() - cpm(1).unwrap()).abs() < 1e-9);
    assert!(cpm(0).unwrap() > 0.0 && cpm(2).is_none());
    assert!(rows[..]
        .table()
        .contains("| late fusion rule (BEV NMS 0.15) |"));
}

#[test]
fn the_fixtures_tracks_score_as_ab3dmots_script_scores_them() {
    // `truth/fixtures/v2v4real/tracks` scored by AB3DMOT's scripts/KITTI/evaluate.py
    // (`late_fusion_Car_train_H1 1 3D 0.25 all train`, the fixture as the AB3DMOT/ folder): its
    // summary to the digits it prints.
    let d = fixture();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../truth/fixtures/v2v4real/tracks");
    let row = score_track_dir(&d, &dir).unwrap();
    // Every unmatched box counted: at least as many false positives, and no higher MOTA.
    assert!(row.counted.fp >= row.metrics.fp && row.counted.mota <= row.metrics.mota);
    let m = &row.metrics;
    let four = |v: f64| format!("{v:.4}");
    assert_eq!(
        [m.samota, m.amota, m.amotp, m.mota, m.motp, m.mt, m.ml, m.recall].map(four),
        ["0.1500", "0.0750", "0.1288", "0.6250", "0.9637", "0.6667", "0.0000", "0.8750"]
    );
    assert_eq!((m.tp, m.fp, m.fn_, m.ids, m.frag), (7, 0, 1, 2, 1));
    assert!((row.boxes_per_frame - 10.0 / 5.0).abs() < 1e-12);
}

#[test]
fn the_ceiling_shows_every_box_with_its_labels_id() {
    let d = fixture();
    let c = ceiling(&d);
    // Eight labelled cars over five frames, every one of them seen by a car; the ego car's false
    // box (30 m from any label) takes a fresh id and, unmatched, costs nothing.
    let boxes: usize = d.cars.iter().flatten().map(Vec::len).sum();
    assert!((c.boxes_per_frame - boxes as f64 / 5.0).abs() < 1e-12);
    assert!((c.metrics.recall - 1.0).abs() < 1e-12, "{:?}", c.metrics);
    assert_eq!((c.metrics.ids, c.metrics.fp), (0, 0), "{:?}", c.metrics);
}

#[test]
fn rows_are_written_where_a_tracker_reads_them() {
    let d = fixture();
    let dir = std::env::temp_dir().join(format!("v2x-rows-{}", std::process::id()));
    let methods = ["csba-wls+".parse().unwrap()];
    let written = write_rows(&d, &sources(&d, &methods), &dir).unwrap();
    let names: Vec<String> = written
        .iter()
        .map(|(p, _)| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "ego-alone",
            "car-1-alone",
            "dataset-late-fusion",
            "late-fusion-rule-bev-nms-0-15",
            "late-fusion-rule-score-0-4",
            "csba-wls-plus"
        ]
    );
    // Read back, each folder scores as its row did.
    let rows = run(&d, &sources(&d, &methods));
    for ((path, n), row) in written.iter().zip(&rows) {
        assert_eq!(*n, row.ap.predictions, "{}", path.display());
        let back = score_detection_dir(&d, path).unwrap();
        for (k, v) in &row.ap.ap_bev {
            assert!((back.ap_bev[k] - v).abs() < 1e-6, "{}", path.display());
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(slug("csba-wls+chi2"), "csba-wls-plus-chi2");
}
