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
        assert!(help.contains(m.name), "{}", m.name);
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

#[test]
fn a_detectors_rows_fuse_with_its_scores_and_without_its_tail() {
    // Sequence 0000: frame 0's car seen by both (0.9 and 0.6: noisy-OR 0.96) and car 1's lone
    // 0.7; frame 1's 0.85 and 0.75; frame 2's 0.8. The 0.25 and 0.3 boxes fall below 0.4.
    let rows = fuse_fixture_cars(&[]);
    let scores: Vec<(u32, f64)> = rows
        .iter()
        .map(|r| {
            let f: Vec<&str> = r.split(',').collect();
            (f[0].parse().unwrap(), f[6].parse().unwrap())
        })
        .collect();
    let mut want: Vec<(u32, f64)> = vec![(0, 0.96), (0, 0.7), (1, 0.85), (1, 0.75), (2, 0.8)];
    let mut got = scores.clone();
    got.sort_by(|a, b| a.0.cmp(&b.0).then(b.1.total_cmp(&a.1)));
    want.sort_by(|a, b| a.0.cmp(&b.0).then(b.1.total_cmp(&a.1)));
    assert_eq!(got.len(), want.len(), "{rows:?}");
    for (g, w) in got.iter().zip(&want) {
        assert!(g.0 == w.0 && (g.1 - w.1).abs() < 1e-9, "{got:?}");
    }
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
fn a_detectors_rows_are_tracked_from_their_first_box_with_their_tail() {
    // Frame 0 of sequence 0000: the pair (0.96), car 1's 0.7 and the ego car's 0.25 box all
    // start tracks shown at once (one hit confirms a detector's track; no tail is dropped).
    let rows = run_on_fixture_cars("track", &[]);
    let frame0: Vec<f64> = rows
        .iter()
        .map(|r| r.split_whitespace().collect::<Vec<_>>())
        .filter(|f| f[0] == "0")
        .map(|f| f[17].parse().unwrap())
        .collect();
    assert_eq!(frame0.len(), 3, "{rows:?}");
    assert!(
        frame0.iter().any(|&s| (s - 0.25).abs() < 1e-9),
        "{frame0:?}"
    );
    // --confirm-hits 2: a box seen once is not shown.
    let rows = run_on_fixture_cars("track", &["--confirm-hits", "2"]);
    assert!(rows.iter().all(|r| !r.starts_with("0 ")), "{rows:?}");
}
