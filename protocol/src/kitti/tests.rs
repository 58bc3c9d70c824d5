use super::*;
use proptest::prelude::*;

const STD: Uncertainty = Uncertainty {
    pos: [0.3; 3],
    size: [0.1; 3],
    yaw: 0.05,
};

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("v2x-kitti-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// V2V4Real's exporter on a box given by its eight LiDAR-frame corners (OpenCOOD's order:
/// bottom 0-3, top 4-7, 0-3 and 1-2 the long sides): `corner_to_center(order='hwl')`, then y
/// and z swapped, as its `transform_and_save_detection_to_ab3dmot_format` writes them.
fn exporter_columns(c: &[[f64; 3]; 8]) -> [f64; 7] {
    let mean = |k: usize| (c[0][k] + c[3][k] + c[5][k] + c[6][k]) / 4.0;
    let h = (0..4).map(|i| c[i + 4][2] - c[i][2]).sum::<f64>().abs() / 4.0;
    let d = |a: usize, b: usize| (c[a][0] - c[b][0]).hypot(c[a][1] - c[b][1]);
    let l = (d(0, 3) + d(2, 1) + d(4, 7) + d(5, 6)) / 4.0;
    let w = (d(0, 1) + d(2, 3) + d(4, 5) + d(6, 7)) / 4.0;
    let a = |p: usize, q: usize| (c[p][1] - c[q][1]).atan2(c[p][0] - c[q][0]);
    let theta = (a(1, 2) + a(0, 3) + a(5, 6) + a(4, 7)) / 4.0;
    [h, w, l, mean(0), mean(2), mean(1), theta]
}

/// OpenCOOD's `boxes_to_corners_3d` of a box (centre, l w h, yaw) in the LiDAR frame.
fn opencood_corners(center: [f64; 3], [l, w, h]: [f64; 3], yaw: f64) -> [[f64; 3]; 8] {
    let template = [
        [1.0, -1.0, -1.0],
        [1.0, 1.0, -1.0],
        [-1.0, 1.0, -1.0],
        [-1.0, -1.0, -1.0],
        [1.0, -1.0, 1.0],
        [1.0, 1.0, 1.0],
        [-1.0, 1.0, 1.0],
        [-1.0, -1.0, 1.0],
    ];
    let (s, co) = yaw.sin_cos();
    template.map(|[a, b, z]| {
        let (x, y) = (a * l / 2.0, b * w / 2.0);
        [
            center[0] + co * x - s * y,
            center[1] + s * x + co * y,
            center[2] + z * h / 2.0,
        ]
    })
}

#[test]
fn the_exporters_columns_read_back_as_the_lidar_box() {
    // A car 12 m ahead and 3 m to the left, its centre 1 m below the sensor, heading 30 degrees
    // to the left of the ego car's x axis.
    let (center, size, yaw) = ([12.0, 3.0, -1.0], [4.5, 1.9, 1.6], 30f64.to_radians());
    let cols = exporter_columns(&opencood_corners(center, size, yaw));
    // The exporter's y is the LiDAR's z (the centre's height), its z the LiDAR's y.
    for (got, want) in cols.iter().zip([1.6, 1.9, 4.5, 12.0, -1.0, 3.0, yaw]) {
        assert!((got - want).abs() < 1e-12, "{cols:?}");
    }
    let text: Vec<String> = cols.iter().map(|v| v.to_string()).collect();
    let row = DetectionRow::parse(&format!("7,2,0,0,0,0,0.62,{},0", text.join(","))).unwrap();
    assert_eq!((row.frame, row.class, row.score), (7, Class::Car, 0.62));
    for k in 0..3 {
        assert!((row.bbox.center[k] - center[k]).abs() < 1e-12);
        assert!((row.bbox.size[k] - size[k]).abs() < 1e-12);
    }
    assert!((row.bbox.yaw - yaw).abs() < 1e-12);
}

#[test]
fn a_label_row_reads_its_track_and_box() {
    let row = TrackRow::parse("3 107 Car 0 0 0 0 0 0 0 1.69 2.07 4.07 -21.05 0.33 1.53 0.18")
        .unwrap()
        .unwrap();
    assert_eq!(
        (row.frame, row.id, row.class, row.score),
        (3, 107, Class::Car, None)
    );
    assert_eq!(row.bbox.center, [-21.05, 1.53, 0.33]);
    assert_eq!(row.bbox.size, [4.07, 2.07, 1.69]);
    assert_eq!(row.bbox.yaw, 0.18);
    let dont_care = "3 -1 DontCare -1 -1 -10 0 0 0 0 -1 -1 -1 -1000 -1000 -1000 -10";
    assert_eq!(TrackRow::parse(dont_care).unwrap(), None);
    let tracked = TrackRow::parse(&format!("{} 0.75", row.write()))
        .unwrap()
        .unwrap();
    assert_eq!(tracked.score, Some(0.75));
}

#[test]
fn bad_rows_name_their_line_and_field() {
    let path = Path::new("ego/0003.txt");
    let good = "0,2,0,0,0,0,0.5,1.5,1.8,4.2,-20.0,-1.0,3.0,0.25,0";
    let cases = [
        (
            "0,2,0,0,0,0,1.5,1.5,1.8,4.2,-20.0,-1.0,3.0,0.25,0",
            Some("score"),
        ),
        (
            "0,7,0,0,0,0,0.5,1.5,1.8,4.2,-20.0,-1.0,3.0,0.25,0",
            Some("type"),
        ),
        ("0,2,0,0,0,0,0.5,1.5,0,4.2,-20.0,-1.0,3.0,0.25,0", Some("w")),
        ("0,2,0,0,0,0,0.5,1.5,1.8,4.2,nan,-1.0,3.0,0.25,0", Some("x")),
        (
            "0,2,0,0,0,0,0.5,1.5,1.8,4.2,-20.0,-1.0,3.0,inf,0",
            Some("ry"),
        ),
        (
            "-1,2,0,0,0,0,0.5,1.5,1.8,4.2,-20.0,-1.0,3.0,0.25,0",
            Some("frame"),
        ),
        ("0,2,0,0,0,0,0.5,1.5,1.8,4.2,-20.0,-1.0,3.0,0.25", None),
    ];
    for (bad, field) in cases {
        let e = parse_detections(path, &format!("{good}\n\n{bad}\n")).unwrap_err();
        assert_eq!((e.line, e.field), (Some(3), field), "{bad}: {e}");
        assert!(e.to_string().starts_with("ego/0003.txt, line 3"), "{e}");
    }
    let e = parse_tracks(path, "0 -1 Car 0 0 0 0 0 0 0 1 1 1 0 0 0 0").unwrap_err();
    assert_eq!((e.line, e.field), (Some(1), Some("id")));
    let e = parse_tracks(path, "0 1 Car 0 0 0 0 0 0 0 1 1 1 0 0 0 0 2.0").unwrap_err();
    assert_eq!(e.field, Some("score"));
}

#[test]
fn a_seqmap_lists_sequences_and_their_frames() {
    let path = Path::new("seqmap");
    let s = parse_seqmap(path, "0000 empty 000000 000146\n0001 empty 000000 000404\n").unwrap();
    assert_eq!(
        s,
        [
            SeqmapEntry {
                seq: 0,
                first: 0,
                last: 146
            },
            SeqmapEntry {
                seq: 1,
                first: 0,
                last: 404
            }
        ]
    );
    let e = parse_seqmap(path, "0000 empty 000010 000002").unwrap_err();
    assert_eq!((e.line, e.field), (Some(1), Some("last")));
}

#[test]
fn a_folder_reads_into_timed_samples_and_writes_back_the_same_rows() {
    let dir = scratch("dir");
    let seq0 = "0,2,0,0,0,0,0.5,1.5,1.8,4.2,-20,-1,3,0.25,0\n\
                0,2,0,0,0,0,0.25,1.6,1.9,4.5,5.5,-0.75,-8,-1.5,0\n\
                2,1,0,0,0,0,0.875,1.75,0.5,0.5,1,-1,2,3,0\n";
    let seq1 = "1,3,0,0,0,0,0.125,1.5,0.5,1.75,10,-1,10,0,0\n";
    std::fs::write(dir.join("0000.txt"), seq0).unwrap();
    std::fs::write(dir.join("0001.txt"), seq1).unwrap();
    std::fs::write(dir.join("notes.md"), "not a sequence").unwrap();
    let r = read_detection_dir(&dir, STD).unwrap();
    assert_eq!(r.order, ["0000_000000", "0000_000002", "0001_000001"]);
    assert_eq!(r.samples["0000_000000"].len(), 2);
    assert_eq!(r.samples["0000_000002"][0].class, Class::Pedestrian);
    assert_eq!(r.samples["0001_000001"][0].std, STD);
    let times = &r.meta["v2x_timestamps"];
    assert_eq!(times["0000_000002"], 200_000);
    assert_eq!(times["0001_000001"], SEQUENCE_US + FRAME_US);

    let out = dir.join("out");
    assert_eq!(write_detection_dir(&out, &r, [0, 1, 5]).unwrap(), 4);
    let text = |n: &str| std::fs::read_to_string(out.join(n)).unwrap();
    assert_eq!(text("0001.txt"), seq1);
    assert_eq!(text("0005.txt"), "");
    let again = read_detection_dir(&out, STD).unwrap();
    assert_eq!(again.samples, r.samples);

    let ids: BTreeMap<String, Vec<u32>> = r
        .samples
        .iter()
        .map(|(t, d)| (t.clone(), (0..d.len() as u32).collect()))
        .collect();
    let tracks = dir.join("tracks");
    assert_eq!(write_track_dir(&tracks, &r, &ids, []).unwrap(), 4);
    let rows = read_tracks(&tracks.join("0000.txt")).unwrap();
    assert_eq!(rows.len(), 3);
    assert_eq!(
        (rows[1].frame, rows[1].id, rows[1].score),
        (0, 1, Some(0.25))
    );
    assert_eq!(rows[2].class, Class::Pedestrian);
    assert_eq!(rows[1].bbox.center, r.samples["0000_000000"][1].center);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_folder_without_sequences_or_a_foreign_sample_is_refused() {
    let dir = scratch("empty");
    let e = read_detection_dir(&dir, STD).unwrap_err();
    assert!(e.message.contains("NNNN.txt"), "{e}");
    let mut r = Results::default();
    r.samples.insert("scene-1-sample".into(), vec![]);
    let e = write_detection_dir(&dir.join("out"), &r, []).unwrap_err();
    assert!(e.message.contains("scene-1-sample"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn tokens_round_trip() {
    assert_eq!(token(3, 42), "0003_000042");
    assert_eq!(parse_token("0003_000042"), Some((3, 42)));
    assert_eq!(parse_token("0003-000042"), None);
    assert_eq!(parse_token("_1"), None);
    assert_eq!(parse_token("1_+2"), None);
}

proptest! {
    #[test]
    fn what_a_row_reads_it_writes_back(
        frame in 0u32..100_000, ty in 1u32..4, score in 0.0f64..=1.0,
        h in 0.01f64..50.0, w in 0.01f64..50.0, l in 0.01f64..50.0,
        x in -1e4f64..1e4, y in -1e4f64..1e4, z in -1e4f64..1e4, ry in -10.0f64..10.0,
        id in 0u32..1_000_000,
    ) {
        let line = format!("{frame},{ty},0,0,0,0,{score},{h},{w},{l},{x},{y},{z},{ry},0");
        let row = DetectionRow::parse(&line).unwrap();
        prop_assert_eq!(DetectionRow::parse(&row.write()).unwrap(), row.clone());
        let t = TrackRow { frame, id, class: row.class, bbox: row.bbox, score: Some(score) };
        prop_assert_eq!(TrackRow::parse(&t.write()).unwrap(), Some(t));
    }
}
