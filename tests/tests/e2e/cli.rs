//! The offline command line: `v2x-sim gen` writes agents' results files, `v2x-fuser fuse` fuses
//! them with every method, `v2x-sim eval` scores the output; bad input gets a clear error.

use std::process::Command;
use v2x_fuser::METHODS;
use v2x_tests::{bin, tempdir, without_fields};

const TOWN: [&str; 8] = [
    "--scenes",
    "2",
    "--seconds",
    "2",
    "--hz",
    "2",
    "--town-seed",
    "3",
];

fn run(cmd: &mut Command) -> (bool, String, String) {
    let out = cmd.output().unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

#[test]
fn gen_fuse_eval_with_every_method() {
    let dir = tempdir("cli");
    let (ok, _, err) = run(Command::new(bin("v2x-sim"))
        .args(["gen", "--noise", "mild", "--seed", "2", "--out"])
        .arg(&dir)
        .args(TOWN));
    assert!(ok, "{err}");
    let (ok, help, _) = run(Command::new(bin("v2x-fuser")).args(["fuse", "--help"]));
    assert!(ok);
    for name in METHODS.iter().filter(|m| !m.ablation).map(|m| &m.name) {
        assert!(help.contains(name), "--help lists {name}");
        let out = dir.join(format!("{name}.json"));
        let (ok, _, err) = run(Command::new(bin("v2x-fuser"))
            .args(["fuse", "--method", name, "--output"])
            .arg(&out)
            .arg(dir.join("agent1.json"))
            .arg(dir.join("agent2.json")));
        assert!(ok, "{name}: {err}");
        let (ok, json, err) = run(Command::new(bin("v2x-sim"))
            .args(["eval", "--format", "json"])
            .args(TOWN)
            .arg(&out));
        assert!(ok, "{name}: {err}");
        let m: serde_json::Value = serde_json::from_str(&json).unwrap();
        let precision = m["precision"].as_f64().unwrap();
        match *name {
            // the gated methods pair every object at mild noise
            "csba-wls+" | "gt-wls" => assert_eq!(precision, 1.0, "{name}"),
            // NMS keeps both agents' copies of objects that do not overlap enough
            "nms-3d" | "nms-giou-3d" | "wbf-3d" => assert!(precision < 0.9, "{name}: {precision}"),
            _ => assert!(precision > 0.45, "{name}: {precision}"),
        }
        assert!(m["recall"].as_f64().unwrap() > 0.95, "{name}: {m}");
    }
    // The fused output keeps the extension fields.
    let text = std::fs::read_to_string(dir.join("csba-wls+.json")).unwrap();
    for field in ["translation_std", "size_std", "yaw_std", "instance_token"] {
        assert!(text.contains(field), "{field}");
    }
}

#[test]
fn missing_stds_and_bad_files_are_clear_errors() {
    let dir = tempdir("cli-errors");
    let (ok, _, err) = run(Command::new(bin("v2x-sim"))
        .args(["gen", "--noise", "mild", "--out"])
        .arg(&dir)
        .args(TOWN));
    assert!(ok, "{err}");
    // Strip the std fields, as a plain detector's output would be.
    let plain = dir.join("plain.json");
    without_fields(
        &dir.join("agent1.json"),
        &plain,
        &["translation_std", "size_std", "yaw_std"],
    );
    let out = dir.join("out.json");
    let (ok, _, err) = run(Command::new(bin("v2x-fuser"))
        .args(["fuse", "--output"])
        .arg(&out)
        .arg(&plain)
        .arg(dir.join("agent2.json")));
    assert!(!ok);
    assert!(
        err.contains("plain.json")
            && err.contains("translation_std")
            && err.contains("--default-std"),
        "{err}"
    );
    let (ok, _, err) = run(Command::new(bin("v2x-fuser"))
        .args(["fuse", "--default-std", "mild", "--output"])
        .arg(&out)
        .arg(&plain)
        .arg(dir.join("agent2.json")));
    assert!(ok, "{err}");
    // A broken file names itself; an unknown method lists the known ones.
    std::fs::write(dir.join("broken.json"), "{\"results\": {\"s\": [{}]}}").unwrap();
    let (ok, _, err) = run(Command::new(bin("v2x-fuser"))
        .args(["fuse", "--output"])
        .arg(&out)
        .arg(dir.join("broken.json")));
    assert!(
        !ok && err.contains("broken.json: sample 's', box 0, field 'translation'"),
        "{err}"
    );
    let (ok, _, err) = run(Command::new(bin("v2x-fuser"))
        .args(["fuse", "--method", "kalman", "--output"])
        .arg(&out)
        .arg(&plain));
    assert!(!ok && err.contains("csba-wls+"), "{err}");
    // Scoring against the wrong ground truth says so.
    let (ok, _, err) = run(Command::new(bin("v2x-sim"))
        .args([
            "eval",
            "--scenes",
            "1",
            "--town-seed",
            "99",
            "--seconds",
            "1",
            "--hz",
            "2",
        ])
        .arg(dir.join("agent2.json")));
    assert!(!ok && err.contains("not in the ground truth"), "{err}");
}

#[test]
fn plot_draws_ground_truth_agents_and_fused_boxes() {
    let dir = tempdir("plot");
    let (ok, _, err) = run(Command::new(bin("v2x-sim"))
        .args(["plot", "--frame", "1", "--noise", "mild+large", "--out"])
        .arg(&dir)
        .args(TOWN));
    assert!(ok, "{err}");
    let svg = std::fs::read_to_string(dir.join("frame-1-mild-large.svg")).unwrap();
    assert!(svg.starts_with("<svg"));
    // every box of the ground truth, both agents and the fused output is a polygon
    let polygons = svg.matches("<polygon").count();
    let gt = svg.matches("stroke=\"#000000\"").count();
    assert!(gt >= 8, "{gt} ground-truth boxes");
    assert!(polygons >= 3 * gt, "{polygons} polygons for {gt} objects");
    assert!(svg.contains("#2ca02c") && svg.contains("#1f77b4") && svg.contains("#ff7f0e"));
}

#[test]
fn files_without_ids_are_scored_by_distance() {
    let dir = tempdir("cli-distance");
    let (ok, _, err) = run(Command::new(bin("v2x-sim"))
        .args(["gen", "--noise", "mild", "--seed", "4", "--out"])
        .arg(&dir)
        .args(TOWN));
    assert!(ok, "{err}");
    // A detector's own output: no ground-truth ids.
    let plain = dir.join("no-ids.json");
    without_fields(&dir.join("agent1.json"), &plain, &["instance_token"]);
    let eval = |file: &std::path::Path, how: &str| {
        let (ok, json, err) = run(Command::new(bin("v2x-sim"))
            .args(["eval", "--format", "json", "--match", how])
            .args(TOWN)
            .arg(file));
        assert!(ok, "{err}");
        (
            serde_json::from_str::<serde_json::Value>(&json).unwrap(),
            err,
        )
    };
    let (auto, note) = eval(&plain, "auto");
    assert!(note.contains("no box carries a ground-truth id"), "{note}");
    let (nds, map) = (auto["NDS"].as_f64().unwrap(), auto["mAP"].as_f64().unwrap());
    // Mild noise: every box within 2 m (AP 1 there), fewer within 0.5 m; the town has no bus
    // or bicycle, and those classes score 0 as in the devkit.
    assert_eq!(auto["recall"].as_f64(), Some(1.0), "{auto}");
    let car = &auto["per_class"]["car"]["AP"];
    assert!((car["2"].as_f64().unwrap() - 1.0).abs() < 1e-9, "{auto}");
    assert!(
        car["0.5"].as_f64().unwrap() < car["1"].as_f64().unwrap(),
        "{auto}"
    );
    assert_eq!(auto["per_class"]["bus"]["mean_AP"].as_f64(), Some(0.0));
    assert!(map > 0.5 && nds > 0.4 && nds < map, "{auto}");
    // Ids play no part in distance matching; matched by id, the same boxes find nothing.
    let (with_ids, _) = eval(&dir.join("agent1.json"), "distance");
    assert_eq!(with_ids["mAP"], auto["mAP"]);
    assert_eq!(with_ids["NDS"], auto["NDS"]);
    let (by_id, _) = eval(&plain, "id");
    assert_eq!(by_id["recall"].as_f64(), Some(0.0));
    // --classes: the headline over the classes named, and a clear error for an unknown one.
    let (ok, json, err) = run(Command::new(bin("v2x-sim"))
        .args(["eval", "--format", "json", "--classes", "car,pedestrian"])
        .args(TOWN)
        .arg(&plain));
    assert!(ok, "{err}");
    let named: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(named["classes"], serde_json::json!(["car", "pedestrian"]));
    let (ok, _, err) = run(Command::new(bin("v2x-sim"))
        .args(["eval", "--classes", "car,tank"])
        .args(TOWN)
        .arg(&plain));
    assert!(!ok && err.contains("unknown class 'tank'"), "{err}");
    // A file with ids is matched by id unless asked otherwise.
    let (ok, _, err) = run(Command::new(bin("v2x-sim"))
        .args(["eval"])
        .args(TOWN)
        .arg(dir.join("agent1.json")));
    assert!(ok && err.contains("matched by ground-truth id"), "{err}");
}

#[test]
fn track_then_score_tracks_and_boxes() {
    // One town scene, 6 s at 10 Hz, moderate noise: tracks follow every object, and the tracked
    // boxes are closer to the truth than the single-frame fused ones.
    let dir = tempdir("track");
    let town = [
        "--scenes",
        "1",
        "--seconds",
        "6",
        "--hz",
        "10",
        "--town-seed",
        "3",
    ];
    let (ok, _, err) = run(Command::new(bin("v2x-sim"))
        .args(["gen", "--noise", "moderate", "--out"])
        .arg(&dir)
        .args(town));
    assert!(ok, "{err}");
    let agents = [dir.join("agent1.json"), dir.join("agent2.json")];
    let (ok, _, err) = run(Command::new(bin("v2x-fuser"))
        .args(["fuse", "--output"])
        .arg(dir.join("fused.json"))
        .args(&agents));
    assert!(
        ok && err.starts_with("csba-wls+: fused"),
        "the default method: {err}"
    );
    // Registration says what it estimated, per window in the file and in sum on stderr.
    let (ok, _, err) = run(Command::new(bin("v2x-fuser"))
        .args(["fuse", "--align", "--output"])
        .arg(dir.join("aligned.json"))
        .args(&agents));
    assert!(
        ok && err.contains("registration of agent1: measured in"),
        "{err}"
    );
    let aligned: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("aligned.json")).unwrap()).unwrap();
    let reports = aligned["meta"]["v2x_registration"].as_object().unwrap();
    assert!(reports
        .values()
        .any(|r| r["agent1"]["matches"].as_u64() > Some(2)));
    let (ok, _, err) = run(Command::new(bin("v2x-fuser"))
        .args(["track", "--output"])
        .arg(dir.join("tracked.json"))
        .args(&agents));
    assert!(ok, "{err}");
    assert!(err.contains("tracks confirmed"), "{err}");
    let text = std::fs::read_to_string(dir.join("tracked.json")).unwrap();
    for field in [
        "tracking_id",
        "tracking_name",
        "tracking_score",
        "detection_name",
    ] {
        assert!(text.contains(field), "{field}");
    }
    // Only the seven classes the devkit's tracking loader accepts, unless asked for all.
    let names = |file: &str| -> std::collections::BTreeSet<String> {
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join(file)).unwrap()).unwrap();
        v["results"]
            .as_object()
            .unwrap()
            .values()
            .flat_map(|b| b.as_array().unwrap().clone())
            .map(|b| b["tracking_name"].as_str().unwrap().to_string())
            .collect()
    };
    let tracking = [
        "bicycle",
        "bus",
        "car",
        "motorcycle",
        "pedestrian",
        "trailer",
        "truck",
    ];
    let seen = names("tracked.json");
    assert!(
        seen.iter().all(|n| tracking.contains(&n.as_str())),
        "{seen:?}"
    );
    let (ok, _, err) = run(Command::new(bin("v2x-fuser"))
        .args(["track", "--all-classes", "--output"])
        .arg(dir.join("all.json"))
        .args(&agents));
    assert!(ok, "{err}");
    let all = names("all.json");
    assert!(
        all.contains("barrier") && all.contains("traffic_cone"),
        "{all:?}"
    );
    let eval = |file: &str, extra: &[&str]| -> serde_json::Value {
        let (ok, json, err) = run(Command::new(bin("v2x-sim"))
            .args(["eval", "--all-frames", "--format", "json"])
            .args(extra)
            .args(town)
            .arg(dir.join(file)));
        assert!(ok, "{file}: {err}");
        serde_json::from_str(&json).unwrap()
    };
    let t = eval("tracked.json", &["--tracking"]);
    assert!(t["MOTA"].as_f64().unwrap() > 0.8, "{t}");
    assert!(t["ids_per_100_tracks"].as_f64().unwrap() <= 5.0, "{t}");
    let fused = eval("fused.json", &["--match", "id"])["mATE"]
        .as_f64()
        .unwrap();
    let tracked = eval("tracked.json", &["--match", "id"])["mATE"]
        .as_f64()
        .unwrap();
    assert!(tracked < 0.9 * fused, "tracked {tracked} fused {fused}");
    // Through the tracks: as good a tracker here, and as close to the truth.
    let (ok, _, err) = run(Command::new(bin("v2x-fuser"))
        .args(["track", "--association", "guided", "--output"])
        .arg(dir.join("guided.json"))
        .args(&agents));
    assert!(ok && err.contains("tracks confirmed"), "{err}");
    let g = eval("guided.json", &["--tracking"]);
    assert!(g["MOTA"].as_f64().unwrap() > 0.8, "{g}");
    assert!(g["ids_per_100_tracks"].as_f64().unwrap() <= 5.0, "{g}");
    let guided = eval("guided.json", &["--match", "id"])["mATE"]
        .as_f64()
        .unwrap();
    assert!(guided < 1.1 * tracked, "guided {guided} tracked {tracked}");
    assert_ne!(
        std::fs::read(dir.join("guided.json")).unwrap(),
        std::fs::read(dir.join("tracked.json")).unwrap()
    );
    // A file that is not a tracking results file, and inputs without capture times.
    let (ok, _, err) = run(Command::new(bin("v2x-sim"))
        .args(["eval", "--tracking"])
        .args(town)
        .arg(dir.join("fused.json")));
    assert!(!ok && err.contains("field 'tracking_id': missing"), "{err}");
    let bare = dir.join("bare.json");
    std::fs::write(
        &bare,
        r#"{"meta": {}, "results": {"s": [{"sample_token": "s", "translation": [0, 0, 0],
        "size": [1, 1, 1], "rotation": [1, 0, 0, 0], "velocity": [0, 0],
        "detection_name": "car", "detection_score": 0.5, "attribute_name": ""}]}}"#,
    )
    .unwrap();
    let (ok, _, err) = run(Command::new(bin("v2x-fuser"))
        .args(["track", "--default-std", "mild", "--output"])
        .arg(dir.join("x.json"))
        .arg(&bare));
    assert!(!ok && err.contains("capture times"), "{err}");
}

fn dair_fixture(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../truth/fixtures/dair")
        .join(name)
}

/// `v2x-sim bench` of csba-wls+ over DAIR-V2X, in JSON.
const DAIR_BENCH: [&str; 7] = [
    "bench",
    "--format",
    "json",
    "--methods",
    "csba-wls+",
    "--dataset",
    "dair-v2x",
];

#[test]
fn dair_v2x_gen_fuse_eval_bench_and_spd_tracks() {
    let dir = tempdir("dair");
    let c = dair_fixture("dair-v2x-c");
    // gen: agent1 = veh, agent2 = inf, keyed by vehicle frame, each with its capture time.
    let (ok, _, err) = run(Command::new(bin("v2x-sim"))
        .args(["gen", "--dataset", "dair-v2x", "--dataroot"])
        .arg(&c)
        .arg("--out")
        .arg(&dir));
    assert!(ok, "{err}");
    let inf: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("agent2.json")).unwrap()).unwrap();
    assert_eq!(inf["meta"]["v2x_agent"], "inf");
    assert_eq!(inf["meta"]["v2x_timestamps"]["000011"], 1626155123080000u64);
    assert_eq!(inf["results"]["000011"].as_array().unwrap().len(), 3);
    // fuse, then eval: the devkit-style figures and the official protocol in one row.
    let (ok, _, err) = run(Command::new(bin("v2x-fuser"))
        .args(["fuse", "--output"])
        .arg(dir.join("fused.json"))
        .arg(dir.join("agent1.json"))
        .arg(dir.join("agent2.json")));
    assert!(ok, "{err}");
    let (ok, out, err) = run(Command::new(bin("v2x-sim"))
        .args([
            "eval",
            "--format",
            "json",
            "--dataset",
            "dair-v2x",
            "--dataroot",
        ])
        .arg(&c)
        .arg(dir.join("fused.json")));
    assert!(ok, "{err}");
    let row: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(row["detection"]["recall"], 1.0);
    let ap = row["dair"]["ap_3d"]["car@0.7"].as_f64().unwrap();
    assert!((ap - 8.0 / 9.0).abs() < 1e-9, "{row}");
    // bench: every row, in JSON; the official byte count of the roadside's three boxes.
    let (ok, out, err) = run(Command::new(bin("v2x-sim"))
        .args(DAIR_BENCH)
        .arg("--dataroot")
        .arg(&c));
    assert!(ok, "{err}");
    let rows: serde_json::Value = serde_json::from_str(&out).unwrap();
    let names: Vec<&str> = rows
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["method"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["veh", "inf", "csba-wls+"]);
    assert_eq!(rows[1]["official_ab"], 216.0);
    // gt-wls needs ground-truth ids, which the labels lack; results need --dataset dair-v2x.
    let (ok, _, err) = run(Command::new(bin("v2x-sim"))
        .args([
            "bench",
            "--methods",
            "gt-wls",
            "--dataset",
            "dair-v2x",
            "--dataroot",
        ])
        .arg(&c));
    assert!(
        !ok && err.contains("gt-wls groups boxes by ground-truth id"),
        "{err}"
    );
    let (ok, _, err) = run(Command::new(bin("v2x-sim"))
        .args(["gen", "--dataroot", "/nonexistent", "--version", "v1.0-x"])
        .args(["--dair-results", "veh=x.json", "--out"])
        .arg(&dir));
    assert!(!ok && err.contains("needs --dataset dair-v2x"), "{err}");
    // A detector's results in the official format replace the roadside's labels.
    let results = serde_json::json!({
        "001010": {"boxes_3d": [], "labels_3d": [], "scores_3d": []},
        "001011": {"boxes_3d": [], "labels_3d": [], "scores_3d": []},
    });
    std::fs::write(dir.join("inf-results.json"), results.to_string()).unwrap();
    let (ok, out, err) = run(Command::new(bin("v2x-sim"))
        .args(DAIR_BENCH)
        .arg("--dair-results")
        .arg(format!("inf={}", dir.join("inf-results.json").display()))
        .arg("--dataroot")
        .arg(&c));
    assert!(ok, "{err}");
    assert!(err.contains("no results for 1 of 3 inf frames"), "{err}");
    let rows: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(
        rows[1]["detection"]["tp"], 0,
        "the roadside detected nothing"
    );
    // V2X-Seq-SPD: its track ids score tracking results.
    let spd = dair_fixture("v2x-seq-spd");
    let (ok, _, err) = run(Command::new(bin("v2x-sim"))
        .args(["gen", "--dataset", "dair-v2x", "--dataroot"])
        .arg(&spd)
        .arg("--out")
        .arg(dir.join("spd")));
    assert!(ok, "{err}");
    let (ok, _, err) = run(Command::new(bin("v2x-fuser"))
        .args(["track", "--confirm-hits", "1", "--output"])
        .arg(dir.join("tracks.json"))
        .arg(dir.join("spd/agent1.json"))
        .arg(dir.join("spd/agent2.json")));
    assert!(ok, "{err}");
    let (ok, out, err) = run(Command::new(bin("v2x-sim"))
        .args([
            "eval",
            "--tracking",
            "--format",
            "json",
            "--dataset",
            "dair-v2x",
            "--dataroot",
        ])
        .arg(&spd)
        .arg(dir.join("tracks.json")));
    assert!(ok, "{err}");
    let m: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(m["gt_tracks"], 3, "{m}");
    assert_eq!(m["IDS"], 0, "{m}");
    assert_eq!(m["tp"], 9, "{m}");
}

#[test]
fn a_closed_standard_output_ends_a_command_quietly() {
    use std::io::Read;
    use std::process::Stdio;
    // Over 64 KiB of JSON, more than a pipe holds, so the writer meets the closed pipe.
    let mut child = Command::new(bin("v2x-sim"))
        .args([
            "bench",
            "--methods",
            "all",
            "--noise",
            "all",
            "--format",
            "json",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut head = [0u8; 16];
    child.stdout.take().unwrap().read_exact(&mut head).unwrap();
    assert_eq!(head[0], b'[');
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(out.status.code(), Some(141), "{err}");
}
