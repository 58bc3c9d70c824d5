use super::*;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/v2v4real/AB3DMOT")
}

fn fixture() -> V2v4real {
    load(&root(), Split::Train, Uncertainty::uniform(0.5, 0.1, 0.1)).unwrap()
}

#[test]
fn the_fixture_loads_frame_by_frame() {
    let d = fixture();
    let f = |seq, frame| FrameRef { seq, frame };
    assert_eq!(d.frames, [f(0, 0), f(0, 1), f(0, 2), f(1, 0), f(1, 1)]);
    assert_eq!(
        d.gt.iter().map(Vec::len).collect::<Vec<_>>(),
        [2, 2, 2, 1, 1]
    );
    assert_eq!(d.boxes(), 8);
    let count = |car: usize| d.cars[car].iter().map(Vec::len).collect::<Vec<_>>();
    assert_eq!(count(0), [2, 1, 2, 1, 0]);
    assert_eq!(count(1), [2, 1, 0, 0, 1]);
    // Labels: KITTI's y is the LiDAR's z; sizes are l, w, h; ids kept.
    let a = &d.gt[0][0];
    assert_eq!(
        (a.center, a.size, a.yaw, a.id),
        ([10.0, 2.0, -1.0], [4.0, 2.0, 1.6], 0.0, 1)
    );
    assert_eq!(d.gt[3][0].id, 7);
    // Detections take the given std and keep their score.
    assert_eq!(d.cars[1][0][1].center, [10.3, 2.0, -1.0]);
    assert_eq!(d.cars[1][0][1].score, 0.6);
    assert_eq!(d.cars[0][0][0].std.pos, [0.5; 3]);
    // Only the late fusion is present in this split.
    assert_eq!(d.references.len(), 1);
    assert_eq!(d.references[0].0, "dataset late fusion");
    assert_eq!(d.references[0].1.iter().map(Vec::len).sum::<usize>(), 2);
    assert_eq!(d.frames[4].capture_us(), 1_000_000_000 + 100_000);
}

#[test]
fn a_missing_split_says_what_the_root_must_hold() {
    let e = load(&root(), Split::Val, Uncertainty::uniform(0.5, 0.1, 0.1)).unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains("v2v4real_val_evaluate_tracking.seqmap.val"),
        "{text}"
    );
    assert!(text.contains("AB3DMOT/"), "{text}");
}

#[test]
fn splits_parse_by_name() {
    assert_eq!("train".parse::<Split>(), Ok(Split::Train));
    assert_eq!("val".parse::<Split>(), Ok(Split::Val));
    assert_eq!("test".parse::<Split>(), Ok(Split::Val));
    assert_eq!(
        "dev".parse::<Split>().unwrap_err().expected,
        ["train", "val"]
    );
}
