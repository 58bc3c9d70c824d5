//! Agents as separate processes: `v2x-sim gen` writes two agents' results files, two
//! `v2x-agent` processes replay them over Zenoh to a `v2x-fuser node` process, which records the
//! fused output; `v2x-sim eval` scores the recording against the same ground truth.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};
use v2x_sim::run::free_port;
use v2x_tests::{bin, tempdir};

fn wait_exit(child: &mut std::process::Child, secs: u64, what: &str) -> std::process::ExitStatus {
    let end = Instant::now() + Duration::from_secs(secs);
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return status;
        }
        if Instant::now() > end {
            let _ = child.kill();
            panic!("{what} did not finish within {secs} s");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// A Unix time `secs` from now, as `--replay start_at=` takes it.
fn start_in(secs: f64) -> String {
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs_f64();
    format!("{:.3}", now + secs)
}

/// A `v2x-fuser node` process with `args`, listening on `endpoint` and recording to `record`.
fn fuser_node(args: &[&str], endpoint: &str, record: &std::path::Path) -> std::process::Child {
    Command::new(bin("v2x-fuser"))
        .arg("node")
        .args(args)
        .args(["--no-multicast-scouting", "-l", endpoint, "--record"])
        .arg(record)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap()
}

/// A command's output, which must have succeeded (`what` names it).
fn succeeded(out: std::process::Output, what: &str) -> std::process::Output {
    assert!(
        out.status.success(),
        "{what}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// A `v2x-agent` process replaying `file` with `args` as `--replay` says, to the fuser at
/// `endpoint`.
fn replay_agent(
    file: &std::path::Path,
    args: &[&str],
    replay: &str,
    endpoint: &str,
) -> std::process::Child {
    Command::new(bin("v2x-agent"))
        .arg(file)
        .args(args)
        .args([
            "--replay",
            replay,
            "--no-multicast-scouting",
            "-e",
            endpoint,
        ])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// Waits for each agent process to finish and checks it sent `sent` ("sent N of N frames").
fn agents_done(agents: Vec<std::process::Child>, sent: &str) {
    for mut a in agents {
        let status = wait_exit(&mut a, 60, "an agent");
        let mut err = String::new();
        std::io::Read::read_to_string(a.stderr.as_mut().unwrap(), &mut err).unwrap();
        assert!(status.success(), "agent failed: {err}");
        assert!(err.contains(sent), "{err}");
    }
}

/// Waits for the fuser process to stop by itself; its statistics.
fn fuser_stats(mut fuser: std::process::Child) -> serde_json::Value {
    let status = wait_exit(&mut fuser, 60, "the fuser");
    assert!(status.success());
    let mut stats = String::new();
    std::io::Read::read_to_string(fuser.stdout.as_mut().unwrap(), &mut stats).unwrap();
    serde_json::from_str(&stats).unwrap()
}

#[test]
fn agents_and_fuser_as_separate_processes() {
    let dir = tempdir("processes");
    let town = [
        "--scenes",
        "1",
        "--seconds",
        "3",
        "--hz",
        "10",
        "--town-seed",
        "9",
    ];
    let out = Command::new(bin("v2x-sim"))
        // A sensing range, so that each agent sees objects the other does not: each process
        // then reads a different set of instance tokens, and the ids must still agree.
        .args([
            "gen",
            "--noise",
            "mild+large",
            "--seed",
            "3",
            "--range",
            "60",
            "--out",
        ])
        .arg(&dir)
        .args(town)
        .output()
        .unwrap();
    succeeded(out, "gen");

    let port = free_port().unwrap();
    // Both agents replay on the real clock from the same start, so their frames meet in windows.
    let replay = format!("start_at={},speed=2", start_in(3.0));
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let record = dir.join("fused.json");
    let args = [
        "--ns",
        "procs",
        "--method",
        "csba-wls+",
        "--max-wait-ms",
        "400",
    ];
    let fuser = fuser_node(
        &[&args[..], &["--duration-s", "8"]].concat(),
        &endpoint,
        &record,
    );
    let agents = [
        ("veh", "vehicle", "agent1.json"),
        ("rsu", "infrastructure", "agent2.json"),
    ]
    .iter()
    .map(|(name, kind, file)| {
        let args = ["--name", name, "--kind", kind, "--ns", "procs"];
        replay_agent(&dir.join(file), &args, &replay, &endpoint)
    })
    .collect();
    agents_done(agents, "sent 30 of 30 frames");
    // The fuser stops by itself after --duration-s and writes its recording and statistics.
    let stats = fuser_stats(fuser);
    assert_eq!(stats["windows"], 30, "{stats}");
    assert_eq!(stats["windows_incomplete"], 0, "{stats}");
    assert_eq!(stats["agents"]["veh"]["fused"], 30);

    let out = Command::new(bin("v2x-sim"))
        .args(["eval", "--format", "json", "--replay", &replay])
        .args(town)
        .arg(&record)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "eval: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let m: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // Every fused box carries its object's id: had the two processes numbered the objects each
    // its own way, the boxes only the roadside unit saw would be false positives.
    assert_eq!(m["precision"], 1.0, "{m}");
    // About half the town lies beyond both agents' 60 m (252 of 510 boxes seen).
    let recall = m["recall"].as_f64().unwrap();
    assert!((0.45..0.55).contains(&recall), "{m}");
    // mild+large: the boxes both saw near the mild agent's error, the roadside unit's own larger.
    let ate = m["mATE"].as_f64().unwrap();
    assert!(ate < 2.2, "{ate}");
}

fn sigterm(child: &std::process::Child) {
    let status = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success(), "kill -TERM");
}

#[tokio::test(flavor = "multi_thread")]
async fn sigterm_makes_the_fuser_node_write_its_recording_and_statistics() {
    use v2x_agent::{Agent, Link};
    use v2x_protocol::AgentKind;
    use v2x_tests::fuser::{connect, endpoint, frame, next_t, wait_live};
    use v2x_tests::within;

    let dir = tempdir("sigterm-node");
    let record = dir.join("fused.json");
    let port = free_port().unwrap();
    let mut fuser = Command::new(bin("v2x-fuser"))
        .args(["node", "--ns", "term", "--no-multicast-scouting", "-l"])
        .arg(endpoint(port))
        .arg("--record")
        .arg(&record)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let session = connect(port).await;
    let mut a = Agent::start(
        &session,
        "term",
        "a",
        AgentKind::Vehicle,
        Link::default(),
        1,
    )
    .await
    .unwrap();
    a.wait_for_subscriber(Duration::from_secs(20))
        .await
        .unwrap();
    wait_live(&session, "term", &["a"]).await;
    let mut last = 0;
    for _ in 0..4 {
        a.send(frame(next_t(&mut last))).unwrap();
    }
    within(20, "four windows fused", async {
        loop {
            if let Ok(v) =
                v2x_fuser::node::query_stats(&session, "term", Duration::from_secs(2)).await
            {
                if v["windows"] == 4 {
                    return;
                }
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    })
    .await;
    sigterm(&fuser);
    let status = wait_exit(&mut fuser, 20, "the fuser after SIGTERM");
    assert!(status.success(), "{status:?}");
    let mut out = String::new();
    std::io::Read::read_to_string(fuser.stdout.as_mut().unwrap(), &mut out).unwrap();
    let stats: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(stats["windows"], 4, "{stats}");
    let rec: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&record).unwrap()).unwrap();
    assert_eq!(rec["results"].as_object().unwrap().len(), 4);
}

#[test]
fn sigterm_makes_a_scenario_run_write_its_recording_and_summary() {
    use std::io::BufRead;
    let dir = tempdir("sigterm-run");
    let record = dir.join("fused.json");
    let mut run = Command::new(bin("v2x-sim"))
        .args(["run", "--format", "json", "--record"])
        .arg(&record)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The default scenario runs 20 s; stop it a few seconds in.
    let mut err = std::io::BufReader::new(run.stderr.take().unwrap());
    let mut line = String::new();
    err.read_line(&mut line).unwrap();
    assert!(line.starts_with("running"), "{line}");
    std::thread::sleep(Duration::from_secs(3));
    sigterm(&run);
    let status = wait_exit(&mut run, 30, "the run after SIGTERM");
    assert!(status.success(), "{status:?}");
    let mut out = String::new();
    std::io::Read::read_to_string(run.stdout.as_mut().unwrap(), &mut out).unwrap();
    let summary: serde_json::Value = serde_json::from_str(&out).unwrap();
    let windows = summary["windows"].as_u64().unwrap();
    assert!(
        (5..150).contains(&windows),
        "{windows} windows before the stop"
    );
    let rec: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&record).unwrap()).unwrap();
    assert_eq!(rec["results"].as_object().unwrap().len() as u64, windows);
}

/// The resident memory of a process (MiB).
fn rss_of(pid: u32) -> f64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| {
            let line = s.lines().find(|l| l.starts_with("VmRSS:"))?.to_string();
            line.split_whitespace().nth(1)?.parse::<f64>().ok()
        })
        .map_or(0.0, |kib| kib / 1024.0)
}

#[tokio::test(flavor = "multi_thread")]
async fn memory_an_attacker_takes_from_the_fuser_comes_back() {
    use v2x_agent::{Agent, Link};
    use v2x_protocol::{keys, wire, AgentKind};
    use v2x_tests::fuser::{connect, endpoint, frame, next_t, wait_live};
    use v2x_tests::within;

    let ns = "memory";
    let port = free_port().unwrap();
    let mut fuser = Command::new(bin("v2x-fuser"))
        .args(["node", "--ns", ns, "--no-multicast-scouting", "-l"])
        .arg(endpoint(port))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let pid = fuser.id();
    let session = connect(port).await;
    let fused = session.declare_subscriber(keys::fused(ns)).await.unwrap();
    let mut a = Agent::start(&session, ns, "a", AgentKind::Vehicle, Link::default(), 1)
        .await
        .unwrap();
    a.wait_for_subscriber(Duration::from_secs(20))
        .await
        .unwrap();
    wait_live(&session, ns, &["a"]).await;
    let mut last = 0;
    let mut round = |a: &mut Agent| a.send(frame(next_t(&mut last))).unwrap();
    let next = || async {
        let s = within(20, "a fused window", fused.recv_async())
            .await
            .unwrap();
        wire::decode(&s.payload().to_bytes()).unwrap()
    };
    for _ in 0..5 {
        round(&mut a);
        next().await;
    }
    let before = rss_of(pid);

    let attacker = connect(port).await;
    let stats = |what: &'static str, cond: fn(&serde_json::Value) -> bool| {
        let session = session.clone();
        async move {
            within(60, what, async {
                loop {
                    if let Ok(v) =
                        v2x_fuser::node::query_stats(&session, ns, Duration::from_secs(2)).await
                    {
                        if cond(&v) {
                            return v;
                        }
                    }
                    tokio::time::sleep(Duration::from_millis(50)).await;
                }
            })
            .await
        }
    };
    let block = zenoh::qos::CongestionControl::Block;
    // One payload of 256 MiB, then a small frame of another name on the same session: the small
    // one arrives, the large one never reaches the fuser (Zenoh drops it before it is put
    // together, else it would be counted as an invalid frame of "big").
    attacker
        .put(keys::detections(ns, "big"), vec![3u8; 256 << 20])
        .congestion_control(block)
        .await
        .unwrap();
    let mut f = frame(now());
    f.agent = "small".into();
    attacker
        .put(keys::detections(ns, "small"), wire::encode(&f).unwrap())
        .congestion_control(block)
        .await
        .unwrap();
    let v = stats("the small frame", |v| v["agents"].get("small").is_some()).await;
    assert!(v["agents"].get("big").is_none(), "{}", v["agents"]);
    // 10,000 agent names, each through a publisher of its own.
    for k in 0..10_000 {
        let name = format!("spam{k}");
        let p = attacker
            .declare_publisher(keys::detections(ns, &name))
            .congestion_control(block)
            .await
            .unwrap();
        let mut f = f.clone();
        f.agent = name;
        p.put(wire::encode(&f).unwrap()).await.unwrap();
    }
    stats("the names processed", |v| {
        v["agents_forgotten"].as_u64().unwrap_or(0) >= 10_000 - 256
    })
    .await;
    let during = rss_of(pid);
    attacker.close().await.unwrap();
    drop(attacker);
    // Within 10 s of the attacker leaving, the fuser is back within 25 MiB of where it was.
    let back = within(10, "the fuser's memory back", async {
        loop {
            let now = rss_of(pid);
            if now <= before + 25.0 {
                return now;
            }
            tokio::time::sleep(Duration::from_millis(200)).await;
        }
    })
    .await;
    eprintln!(
        "fuser RSS: {before:.1} MiB before, {during:.1} MiB during the attack, {back:.1} MiB after"
    );
    // And the honest agent is still fused.
    round(&mut a);
    let f = next().await;
    assert_eq!(f.detections.len(), 2);
    let _ = fuser.kill();
    let _ = fuser.wait();
}

fn now() -> u64 {
    v2x_agent::now_us()
}

/// The fused boxes' scores per window of a results file, in time order, windows without a box
/// left out; each window's scores in descending order.
fn scores_by_window(path: &std::path::Path) -> Vec<Vec<f64>> {
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let results = doc["results"].as_object().unwrap();
    let time = |k: &str| -> u64 {
        match doc["meta"]["v2x_timestamps"].get(k) {
            Some(t) => t.as_u64().unwrap(),
            None => k.trim_start_matches('t').parse().unwrap(),
        }
    };
    let mut windows: Vec<(u64, Vec<f64>)> = results
        .iter()
        .map(|(k, boxes)| {
            let mut s: Vec<f64> = boxes
                .as_array()
                .unwrap()
                .iter()
                .map(|b| b["detection_score"].as_f64().unwrap())
                .collect();
            s.sort_by(|a, b| b.total_cmp(a));
            (time(k), s)
        })
        .filter(|(_, s)| !s.is_empty())
        .collect();
    windows.sort_by_key(|(t, _)| *t);
    windows.into_iter().map(|(_, s)| s).collect()
}

#[test]
fn v2v4real_cars_replayed_as_processes_fuse_as_offline() {
    // `v2x-sim gen --dataset v2v4real` on the layout's fixture, both cars replayed by
    // `v2x-agent` to `v2x-fuser node --detector`: each window as `v2x-fuser fuse --detector`.
    let dir = tempdir("v2v4real-processes");
    let root =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../truth/fixtures/v2v4real/AB3DMOT");
    let out = Command::new(bin("v2x-sim"))
        .args([
            "gen",
            "--dataset",
            "v2v4real",
            "--split",
            "train",
            "--dataroot",
        ])
        .arg(&root)
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    succeeded(out, "gen");
    let (a1, a2) = (dir.join("agent1.json"), dir.join("agent2.json"));
    let offline = dir.join("offline.json");
    let out = Command::new(bin("v2x-fuser"))
        .args(["fuse", "--detector", "-o"])
        .arg(&offline)
        .arg(&a1)
        .arg(&a2)
        .output()
        .unwrap();
    succeeded(out, "fuse");

    let port = free_port().unwrap();
    let replay = format!("start_at={},speed=4", start_in(3.0));
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let record = dir.join("fused.json");
    let args = [
        "--ns",
        "v2v",
        "--detector",
        "--max-wait-ms",
        "400",
        "--duration-s",
        "7",
    ];
    let fuser = fuser_node(&args, &endpoint, &record);
    let agents = [("ego", &a1), ("car1", &a2)]
        .iter()
        .map(|(name, file)| {
            let args = ["--name", name, "--ns", "v2v"];
            replay_agent(file, &args, &replay, &endpoint)
        })
        .collect();
    agents_done(agents, "sent 5 of 5 frames");
    let stats = fuser_stats(fuser);
    assert_eq!(stats["windows"], 5, "{stats}");

    // Frame 0 of sequence 0000: the pair (0.9, 0.6) and car 1's lone 0.7, each scored by its
    // chance of being real; the ego car's 0.25 box falls below 0.2 in both. The node does not
    // know which agent receives the others' boxes, so its scores lack the existence model's
    // receiver term (weight -0.17 on the log-odds: at most 0.05 on a chance).
    let (live, off) = (scores_by_window(&record), scores_by_window(&offline));
    assert_eq!(live.len(), off.len(), "{live:?} against {off:?}");
    assert!(off[0][0] > 0.99 && off[0].len() == 2, "{off:?}");
    for (l, o) in live.iter().zip(&off) {
        assert_eq!(l.len(), o.len(), "{live:?} against {off:?}");
        for (a, b) in l.iter().zip(o) {
            // Scores also cross the wire in 1/255 steps.
            assert!((a - b).abs() < 0.05, "{live:?} against {off:?}");
        }
    }
}
