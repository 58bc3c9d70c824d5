//! The `v2x-fuser` binary: help lists every method, bad input fails with one clear line.
//! (This integration test also makes `cargo test` build the binary the end-to-end tests run.)

use std::process::Command;

#[test]
fn help_lists_methods_and_errors_are_one_line() {
    let exe = env!("CARGO_BIN_EXE_v2x-fuser");
    let out = Command::new(exe).args(["fuse", "--help"]).output().unwrap();
    assert!(out.status.success());
    let help = String::from_utf8(out.stdout).unwrap();
    for m in v2x_fuser::METHODS {
        // The ablations are the bench's rows, not the fuser's choices.
        assert_eq!(help.contains(m.name), !m.ablation, "{}", m.name);
    }
    let out = Command::new(exe)
        .args([
            "fuse",
            "--output",
            "/tmp/never.json",
            "/nonexistent/agent1.json",
        ])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(
        err.starts_with("error: /nonexistent/agent1.json: cannot read"),
        "{err}"
    );
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
}

#[test]
fn node_and_router_explain_their_options_and_refuse_bad_ones() {
    let exe = env!("CARGO_BIN_EXE_v2x-fuser");
    let out = Command::new(exe).args(["node", "--help"]).output().unwrap();
    let help = String::from_utf8(out.stdout).unwrap();
    for flag in [
        "--max-clock-skew-ms",
        "--max-agents",
        "--forget-after-s",
        "SIGTERM",
    ] {
        assert!(help.contains(flag), "{flag}");
    }
    let out = Command::new(exe)
        .args(["router", "--help"])
        .output()
        .unwrap();
    let help = String::from_utf8(out.stdout).unwrap();
    assert!(
        help.contains("--zenoh-config") && help.contains("peer mode"),
        "{help}"
    );
    for args in [
        &["node", "--max-clock-skew-ms", "-5"][..],
        &["node", "--duration-s", "nan"],
        &["node", "--max-agents", "0"],
    ] {
        let out = Command::new(exe).args(args).output().unwrap();
        assert!(!out.status.success(), "{args:?}");
        let err = String::from_utf8(out.stderr).unwrap();
        assert!(err.starts_with("error:"), "{args:?}: {err}");
    }
    let out = Command::new(exe)
        .args(["router", "--zenoh-config", "/nonexistent/router.json5"])
        .output()
        .unwrap();
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(
        !out.status.success() && err.contains("/nonexistent/router.json5"),
        "{err}"
    );
}

/// Fuses the V2V4Real-layout fixture's two cars with `v2x-fuser fuse` and `extra` flags; the
/// output's rows of sequence 0000.
fn fuse_fixture_cars(extra: &[&str]) -> Vec<String> {
    run_on_fixture_cars("fuse", extra)
}

/// `v2x-fuser COMMAND --output-format kitti` over the V2V4Real-layout fixture's two cars; the
/// output's rows of sequence 0000.
fn run_on_fixture_cars(command: &str, extra: &[&str]) -> Vec<String> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(
        "../truth/fixtures/v2v4real/AB3DMOT/data/v2v4real/detection/multi_sensor_differentiable_kalman_filter_Car_train",
    );
    let out = std::env::temp_dir().join(format!(
        "v2x-kitti-{command}-{}-{}",
        std::process::id(),
        extra.len()
    ));
    let status = Command::new(env!("CARGO_BIN_EXE_v2x-fuser"))
        .args([command, "--output-format", "kitti", "--output"])
        .arg(&out)
        .args(extra)
        .arg(root.join("ego"))
        .arg(root.join("1"))
        .output()
        .unwrap();
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    let rows = std::fs::read_to_string(out.join("0000.txt")).unwrap();
    assert!(out.join("0001.txt").is_file());
    std::fs::remove_dir_all(&out).unwrap();
    rows.lines().map(str::to_string).collect()
}

/// Each fused row's frame and score, by frame and then score, highest first.
fn frame_scores(rows: &[String]) -> Vec<(u32, f64)> {
    let mut got: Vec<(u32, f64)> = rows
        .iter()
        .map(|r| {
            let f: Vec<&str> = r.split(',').collect();
            (f[0].parse().unwrap(), f[6].parse().unwrap())
        })
        .collect();
    got.sort_by(|a, b| a.0.cmp(&b.0).then(b.1.total_cmp(&a.1)));
    got
}

#[test]
fn a_detectors_rows_fuse_with_its_scores_and_without_its_tail() {
    // Sequence 0000: frame 0's car seen by both (0.9 and 0.6) and car 1's lone 0.7, with the
    // ego car's 0.25 box 42 m out; frame 1's 0.85 and 0.75; frame 2's 0.8 and the ego car's
    // 0.3. Scored by the chance each is real, the pair ranks above the noisy-OR of its members
    // (0.96) and the 0.25 box falls below 0.2; the 0.3 box near the ego car stays.
    let rows = fuse_fixture_cars(&[]);
    let got = frame_scores(&rows);
    let frames: Vec<u32> = got.iter().map(|g| g.0).collect();
    assert_eq!(frames, [0, 0, 1, 1, 2, 2], "{got:?}");
    assert!(got[0].1 > 0.99, "{got:?}");
    assert!(got[5].1 >= 0.2 && got[5].1 < 0.3, "{got:?}");
    // --min-score 0 keeps the 0.25 box, scored below every other.
    let all = frame_scores(&fuse_fixture_cars(&["--min-score", "0"]));
    assert_eq!(all.len(), 7);
    assert!(all.iter().all(|g| g.1 > 0.0 && g.1 < 1.0));
    assert!(
        all.iter().filter(|g| g.1 < got[5].1).count() == 1,
        "{all:?}"
    );
    // The members' noisy-OR and a cut at 0.4, exactly.
    let noisy = frame_scores(&fuse_fixture_cars(&[
        "--existence-model",
        "noisy-or",
        "--min-score",
        "0.4",
    ]));
    let want = [(0, 0.96), (0, 0.7), (1, 0.85), (1, 0.75), (2, 0.8)];
    assert_eq!(noisy.len(), want.len(), "{noisy:?}");
    for (g, w) in noisy.iter().zip(&want) {
        assert!(g.0 == w.0 && (g.1 - w.1).abs() < 1e-9, "{noisy:?}");
    }
    // A model file is read, and one of another build's features is refused by name.
    let dir = std::env::temp_dir().join(format!("v2x-existence-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model = dir.join("model.json");
    let file = v2x_fuser::uncertainty::existence::DETECTOR_DEFAULT.to_file([1, 1]);
    std::fs::write(&model, serde_json::to_string(&file).unwrap()).unwrap();
    assert_eq!(
        fuse_fixture_cars(&["--existence-model", model.to_str().unwrap()]),
        rows
    );
    let mut wrong = file;
    wrong.weights[0].0 = "score".into();
    std::fs::write(&model, serde_json::to_string(&wrong).unwrap()).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_v2x-fuser"))
        .args(["fuse", "--existence-model"])
        .arg(&model)
        .args(["-o", "x", "a.json"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("model.json") && err.contains("\"score\""),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
    // Stated stds are the user's choice: every box is kept, scored as the paper fuses.
    let stated = fuse_fixture_cars(&["--default-std", "mild"]);
    assert_eq!(stated.len(), 7, "{stated:?}");
    // --detector asks for what KITTI folders get by default, and is no std of its own.
    assert_eq!(fuse_fixture_cars(&["--detector"]), rows);
    let out = Command::new(env!("CARGO_BIN_EXE_v2x-fuser"))
        .args([
            "fuse",
            "--detector",
            "--default-std",
            "mild",
            "-o",
            "x",
            "a.json",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("--default-std"),
        "{err}"
    );
}

#[test]
fn a_detectors_rows_are_tracked_with_their_tail_from_their_second_box() {
    // Two boxes in a row confirm a detector's track: nothing is shown in frame 0, and frame 1
    // shows the car both agents see and car 1's car. The tracker gets every box, and the
    // operating point (0.2) applies to what it shows: with one hit the ego car's 0.25 box (its
    // chance 0.10) starts a track in frame 0, shown only with --min-score 0.
    let rows = run_on_fixture_cars("track", &[]);
    let frame = |rows: &[String], k: &str| -> Vec<f64> {
        rows.iter()
            .map(|r| r.split_whitespace().collect::<Vec<_>>())
            .filter(|f| f[0] == k)
            .map(|f| f[17].parse().unwrap())
            .collect()
    };
    assert!(frame(&rows, "0").is_empty(), "{rows:?}");
    assert_eq!(frame(&rows, "1").len(), 2, "{rows:?}");
    let rows = run_on_fixture_cars("track", &["--confirm-hits", "1"]);
    assert_eq!(frame(&rows, "0").len(), 2, "{rows:?}");
    let rows = run_on_fixture_cars("track", &["--confirm-hits", "1", "--min-score", "0"]);
    let frame0 = frame(&rows, "0");
    assert_eq!(frame0.len(), 3, "{rows:?}");
    assert!(frame0.iter().any(|&s| s > 0.1 && s < 0.11), "{frame0:?}");
}
