//! Learned stds over loopback Zenoh (`scenarios/learn-std.toml`): a roadside unit whose boxes
//! carry 3 m of noise but state 0.5 m splits a third of the fused groups; the fuser node that
//! learns each agent's stds (`fuser.learn_std`) fuses as if it had stated them honestly, and
//! flags it in its statistics within the first second.

use v2x_sim::run::run_local;
use v2x_sim::scenario::Scenario;
use v2x_tests::{bin, tempdir, within, without_fields};

/// The scenario file for 8 s of data at twice real time, in its own namespace, edited by `edit`.
fn scenario(ns: &str, edit: &dyn Fn(String) -> String) -> Scenario {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/learn-std.toml");
    let toml = std::fs::read_to_string(path)
        .unwrap()
        .replace("duration_s = 20.0", "duration_s = 8.0")
        .replace("speed = 1.0", "speed = 2.0")
        .replace(
            "namespace = \"learn-std\"",
            &format!("namespace = \"{ns}\""),
        );
    Scenario::parse(&edit(toml), ns, None).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_overconfident_agent_is_learned_and_flagged_over_the_network() {
    // A calibrated model of the roadside unit, from another draw of the same town.
    let dir = tempdir("learn-net-model");
    let town = [
        "--scenes",
        "1",
        "--seconds",
        "20",
        "--hz",
        "10",
        "--town-seed",
        "7",
    ];
    let (ok, _, err) = run(std::process::Command::new(bin("v2x-sim"))
        .args(["gen", "--noise", "mild+large", "--seed", "2", "--out"])
        .arg(&dir)
        .args(town));
    assert!(ok, "{err}");
    let model = dir.join("rsu.json");
    let (ok, _, err) = run(std::process::Command::new(bin("v2x-sim"))
        .arg("calibrate")
        .args(town)
        .arg(dir.join("agent2.json"))
        .arg("-o")
        .arg(&model));
    assert!(ok, "{err}");
    let with_model = format!(
        "learn_std = false\nstd_models = {{ rsu = {:?} }}",
        model.display().to_string()
    );
    let mut runs = Vec::new();
    for (ns, edit) in [
        ("learn-on", Box::new(|t| t) as Box<dyn Fn(String) -> String>),
        (
            "learn-off",
            Box::new(|t: String| t.replace("learn_std = true", "learn_std = false")),
        ),
        (
            "learn-honest",
            Box::new(|t: String| {
                t.replace("learn_std = true", "learn_std = false")
                    .replace("stated_std = \"mild\"", "")
            }),
        ),
        (
            "learn-model",
            Box::new(move |t: String| t.replace("learn_std = true", &with_model)),
        ),
    ] {
        let s = scenario(ns, &*edit);
        let gt = s.dataset.data_args().load().unwrap();
        let (summary, _) = within(90, ns, run_local(&s, &gt)).await.unwrap();
        runs.push(summary);
    }
    let [learned, stated, honest, modelled] = &runs[..] else {
        unreachable!()
    };
    let fig = |s: &v2x_sim::run::summary::Summary| {
        (s.fused.precision.unwrap(), s.fused.all.m_ate.unwrap())
    };
    let ((p_learned, e_learned), (p_stated, e_stated), (_, e_honest), (p_model, e_model)) =
        (fig(learned), fig(stated), fig(honest), fig(modelled));
    // Calibrated: as good as honest stds.
    assert!(p_model >= 0.98, "{p_model}");
    assert!(e_model <= 1.05 * e_honest, "{e_model} vs {e_honest}");
    // What the stated stds do: groups split, the fused error triples.
    assert!(p_stated < 0.8, "{p_stated}");
    assert!(e_stated > 2.0 * e_honest, "{e_stated} vs {e_honest}");
    // Learned: as good as honest stds.
    assert!(p_learned >= 0.98, "{p_learned}");
    assert!(e_learned <= 1.1 * e_honest, "{e_learned} vs {e_honest}");
    // The roadside unit is flagged (its stds are about 6x too small) within a second of data;
    // the vehicle, honest, never.
    let flagged = &learned.std_flagged_after_s;
    assert!(flagged["rsu"] <= 1.0, "{flagged:?}");
    assert!(!flagged.contains_key("veh"), "{flagged:?}");
    let rsu = &learned.learned_std["rsu"];
    let ratio = rsu.ratio_xy.unwrap();
    assert!((4.5..7.0).contains(&ratio), "rsu stds off by {ratio}");
    assert!(rsu.classes.contains_key("car"));
    assert!(stated.learned_std.is_empty() && stated.std_flagged_after_s.is_empty());
}

/// Runs a command; (success, stdout, stderr).
fn run(cmd: &mut std::process::Command) -> (bool, String, String) {
    let out = cmd.output().unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

/// The synthetic town for 10 s at 10 Hz.
const TOWN: [&str; 6] = ["--scenes", "1", "--seconds", "10", "--hz", "10"];

/// `v2x-sim gen` of a mild vehicle and a large-noise roadside unit stating `stated` into `dir`.
fn gen(dir: &std::path::Path, stated: &str) {
    let (ok, _, err) = run(std::process::Command::new(bin("v2x-sim"))
        .args([
            "gen",
            "--noise",
            "mild+large",
            "--stated-std",
            stated,
            "--out",
        ])
        .arg(dir)
        .args(TOWN));
    assert!(ok, "{err}");
}

/// Fuses `dir`'s two agents with `extra` flags; (precision, mATE, stderr).
fn fuse(dir: &std::path::Path, extra: &[&str]) -> (f64, f64, String) {
    let out = dir.join("fused.json");
    let (ok, _, err) = run(std::process::Command::new(bin("v2x-fuser"))
        .arg("fuse")
        .args(extra)
        .arg("--output")
        .arg(&out)
        .arg(dir.join("agent1.json"))
        .arg(dir.join("agent2.json")));
    assert!(ok, "{err}");
    let (ok, json, e) = run(std::process::Command::new(bin("v2x-sim"))
        .args(["eval", "--match", "id", "--format", "json"])
        .args(TOWN)
        .arg(&out));
    assert!(ok, "{e}");
    let m: serde_json::Value = serde_json::from_str(&json).unwrap();
    (
        m["precision"].as_f64().unwrap(),
        m["mATE"].as_f64().unwrap(),
        err,
    )
}

#[test]
fn fuse_learns_stds_stated_wrong_or_not_at_all() {
    let honest = tempdir("learn-honest");
    gen(&honest, "honest");
    let (p_honest, e_honest, _) = fuse(&honest, &[]);
    assert!(p_honest > 0.99, "{p_honest}");

    // The roadside unit states a sixth of its noise: groups split until its stds are learned.
    let over = tempdir("learn-over");
    gen(&over, "honest+x0.1667");
    let (p, e, _) = fuse(&over, &[]);
    assert!(p < 0.8 && e > 2.0 * e_honest, "{p} {e} vs {e_honest}");
    let (p, e, err) = fuse(&over, &["--learn-std"]);
    assert!(p >= 0.98 && e <= 1.1 * e_honest, "{p} {e} vs {e_honest}");
    assert!(
        err.contains("learned stds of agent2") && err.contains("flagged"),
        "{err}"
    );
    let fused: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(over.join("fused.json")).unwrap()).unwrap();
    let learned = &fused["meta"]["v2x_learned_std"];
    assert_eq!(learned["agent2"]["flagged"], true);
    assert_eq!(learned["agent1"]["flagged"], false);
    let rho = learned["agent2"]["all"]["pos_xy"]["ratio"]
        .as_f64()
        .unwrap();
    assert!((4.5..7.5).contains(&rho), "{rho}");

    // The vehicle states six times its noise: flagged the other way.
    let under = tempdir("learn-under");
    gen(&under, "x6+honest");
    let (_, e, err) = fuse(&under, &["--learn-std"]);
    assert!(e <= 1.1 * e_honest, "{e} vs {e_honest}");
    assert!(
        err.contains("learned stds of agent1") && err.contains("x0.1"),
        "{err}"
    );

    // No stds at all: --learn-std needs no --default-std.
    let none = tempdir("learn-none");
    gen(&none, "none");
    let text = std::fs::read_to_string(none.join("agent2.json")).unwrap();
    assert!(!text.contains("translation_std"));
    let (p, e, _) = fuse(&none, &["--learn-std"]);
    assert!(p >= 0.98 && e <= 1.1 * e_honest, "{p} {e} vs {e_honest}");

    // A calibrated model of the roadside unit, from another draw: as good as honest stds.
    let other = tempdir("learn-calibrate");
    let (ok, _, err) = run(std::process::Command::new(bin("v2x-sim"))
        .args(["gen", "--noise", "mild+large", "--seed", "5", "--out"])
        .arg(&other)
        .args(TOWN));
    assert!(ok, "{err}");
    let model = other.join("rsu-model.json");
    let (ok, table, err) = run(std::process::Command::new(bin("v2x-sim"))
        .arg("calibrate")
        .args(TOWN)
        .arg(other.join("agent2.json"))
        .arg("--output")
        .arg(&model));
    assert!(ok && err.contains("matched by ground-truth id"), "{err}");
    assert!(
        table.contains("| car |") && table.contains("| all |"),
        "{table}"
    );
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    let s = m["all"]["std"]["center"][0].as_f64().unwrap();
    assert!((s / 3.0 - 1.0).abs() < 0.05, "{s}");
    let arg = format!("agent2={}", model.display());
    let (p, e, _) = fuse(&over, &["--std-model", &arg]);
    assert!(p >= 0.98 && e <= 1.05 * e_honest, "{p} {e} vs {e_honest}");
    // With a model for every input, boxes need no stds.
    let veh = other.join("veh-model.json");
    let (ok, _, err) = run(std::process::Command::new(bin("v2x-sim"))
        .args(["calibrate", "--score-bins", "1"])
        .args(TOWN)
        .arg(other.join("agent1.json"))
        .arg("-o")
        .arg(&veh));
    assert!(ok, "{err}");
    let veh_arg = format!("agent1={}", veh.display());
    let (p, e, _) = fuse(&none, &["--std-model", &arg, "--std-model", &veh_arg]);
    assert!(p >= 0.98 && e <= 1.05 * e_honest, "{p} {e} vs {e_honest}");
    // Bad models and names are named.
    let fail = |args: &[&str]| {
        let (ok, _, err) = run(std::process::Command::new(bin("v2x-fuser"))
            .arg("fuse")
            .args(args)
            .arg("--output")
            .arg(over.join("x.json"))
            .arg(over.join("agent1.json"))
            .arg(over.join("agent2.json")));
        assert!(!ok);
        err
    };
    let err = fail(&["--std-model", &format!("rsu={}", model.display())]);
    assert!(
        err.contains("--std-model rsu") && err.contains("agentN"),
        "{err}"
    );
    let err = fail(&["--std-model", "agent2=/nonexistent/m.json"]);
    assert!(err.contains("/nonexistent/m.json"), "{err}");
    let not_a_model = format!("agent2={}", over.join("agent1.json").display());
    let err = fail(&["--std-model", &not_a_model]);
    assert!(err.contains("agent1.json"), "{err}");
    // A detector's own boxes carry no ground-truth ids to calibrate by: matched by distance.
    let plain_path = other.join("plain.json");
    without_fields(&other.join("agent2.json"), &plain_path, &["instance_token"]);
    let calibrate = |how: &str| {
        run(std::process::Command::new(bin("v2x-sim"))
            .args(["calibrate", "--match", how])
            .args(TOWN)
            .arg(&plain_path)
            .arg("-o")
            .arg(other.join("x.json")))
    };
    let (ok, _, err) = calibrate("id");
    assert!(
        !ok && err.contains("plain.json") && err.contains("--match distance"),
        "{err}"
    );
    let (ok, _, err) = calibrate("auto");
    assert!(ok && err.contains("centre distance within 4 m"), "{err}");

    // Learning follows capture times: a file without them is named.
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["meta"] = serde_json::json!({});
    std::fs::write(none.join("agent2.json"), v.to_string()).unwrap();
    let (ok, _, err) = run(std::process::Command::new(bin("v2x-fuser"))
        .args(["fuse", "--learn-std", "--output"])
        .arg(none.join("x.json"))
        .arg(none.join("agent1.json"))
        .arg(none.join("agent2.json")));
    assert!(
        !ok && err.contains("agent2.json") && err.contains("v2x_timestamps"),
        "{err}"
    );
}
