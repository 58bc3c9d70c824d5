//! Helpers for the end-to-end tests in `tests/tests/`: locating the workspace's binaries,
//! building small scenarios, waiting with a timeout, and driving a fuser node ([`fuser`]).

use std::path::PathBuf;
use std::time::Duration;

/// The path of a workspace binary built beside the running test (`cargo test --workspace` builds
/// them, because each binary's own package has an integration test that runs it).
pub fn bin(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let dir = exe
        .parent()
        .and_then(|d| d.parent())
        .expect("target profile directory");
    let p = dir.join(name);
    assert!(
        p.exists(),
        "{} is not built: run the tests with `cargo test --workspace`",
        p.display()
    );
    p
}

/// A scenario on a small synthetic town: `agents` agents with the given noises (cycled), no link
/// impairment, replayed `speed` times faster than real time.
pub fn scenario_toml(
    ns: &str,
    noises: &[&str],
    agents: usize,
    duration_s: f64,
    speed: f64,
    method: &str,
) -> String {
    let mut s = format!("namespace = \"{ns}\"\nseed = 4\nduration_s = {duration_s}\nspeed = {speed}\n\n[dataset]\nscenes = 1\nseconds = {duration_s}\nhz = 10.0\ntown_seed = 5\n\n[fuser]\nmethod = \"{method}\"\nmax_wait_ms = 400.0\n");
    for i in 0..agents {
        let kind = if i == 1 { "infrastructure" } else { "vehicle" };
        s.push_str(&format!(
            "\n[[agents]]\nname = \"a{i}\"\nkind = \"{kind}\"\nnoise = \"{}\"\n",
            noises[i % noises.len()]
        ));
    }
    s
}

/// Waits for `f` with a timeout, failing the test with `what` when it expires.
pub async fn within<T>(secs: u64, what: &str, f: impl std::future::Future<Output = T>) -> T {
    tokio::time::timeout(Duration::from_secs(secs), f)
        .await
        .unwrap_or_else(|_| panic!("timed out after {secs} s: {what}"))
}

/// A fresh temporary directory for one test.
pub fn tempdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("v2x-e2e-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("create temp dir");
    d
}

/// Copies a results file without the given fields in any box, as a detector's own output
/// (no stds, no ground-truth ids) would be.
pub fn without_fields(src: &std::path::Path, dst: &std::path::Path, fields: &[&str]) {
    let text = std::fs::read_to_string(src).expect("read the results file");
    let mut v: serde_json::Value = serde_json::from_str(&text).expect("results JSON");
    let boxes = v["results"].as_object_mut().expect("a results object");
    for b in boxes
        .values_mut()
        .filter_map(|s| s.as_array_mut())
        .flatten()
    {
        let b = b.as_object_mut().expect("box objects");
        for f in fields {
            b.remove(*f);
        }
    }
    std::fs::write(dst, v.to_string()).expect("write the results file");
}

/// A fuser node in the test process, and frames to feed it.
pub mod fuser {
    use crate::within;
    use std::collections::BTreeSet;
    use std::time::Duration;
    use tokio::sync::mpsc;
    use v2x_agent::{now_us, Agent, Link};
    use v2x_fuser::node::{self, Fused, NodeConfig};
    use v2x_protocol::net::{open_session, ZenohArgs};
    use v2x_protocol::{AgentKind, Detection, Frame};

    /// A car at (x, 0) with mild stds and the given id.
    pub fn det(x: f64, id: u32) -> Detection {
        Detection {
            center: [x, 0.0, 0.8],
            id,
            ..v2x_protocol::fixtures::car(x, 0.0, 0.5)
        }
    }

    /// The capture time of the next window: now, and at least one window (100 ms) after the last.
    pub fn next_t(last: &mut u64) -> u64 {
        *last = now_us().max(*last + 100_000);
        *last
    }

    /// A frame captured at `t_us` (the sender's real-time clock, as the fuser expects).
    pub fn frame(t_us: u64) -> Frame {
        Frame {
            agent: String::new(),
            kind: AgentKind::Vehicle,
            seq: 0,
            capture_us: t_us,
            origin: [0.0; 3],
            detections: vec![det(10.0, 1), det(30.0, 2)],
        }
    }

    /// The loopback TCP endpoint of a port.
    pub fn endpoint(port: u16) -> String {
        format!("tcp/127.0.0.1:{port}")
    }

    /// A session on loopback listening on `port`.
    pub async fn listen(port: u16) -> zenoh::Session {
        let args = ZenohArgs::loopback(&[endpoint(port)], &[]);
        open_session(&args)
            .await
            .expect("a session listening on loopback")
    }

    /// A session on loopback connected to `port`.
    pub async fn connect(port: u16) -> zenoh::Session {
        let args = ZenohArgs::loopback(&[], &[endpoint(port)]);
        open_session(&args)
            .await
            .expect("a session connected on loopback")
    }

    /// Agent `name` started on `session` with a perfect link, once a fuser subscribes to it (10 s
    /// at most).
    pub async fn joined(
        session: &zenoh::Session,
        ns: &str,
        name: &str,
        kind: AgentKind,
        seed: u64,
    ) -> Agent {
        let agent = Agent::start(session, ns, name, kind, Link::default(), seed)
            .await
            .expect("the agent starts");
        agent
            .wait_for_subscriber(Duration::from_secs(10))
            .await
            .expect("a fuser subscribes to the agent");
        agent
    }

    /// A running fuser node: stop it, read its fused windows, await its final statistics.
    pub type FuserHandle = (
        tokio::sync::oneshot::Sender<()>,
        mpsc::UnboundedReceiver<Fused>,
        tokio::task::JoinHandle<node::NodeStats>,
    );

    /// Starts a csba-wls+ fuser node with the default limits and the given wait.
    pub fn spawn_fuser(session: zenoh::Session, ns: &str, max_wait_ms: f64) -> FuserHandle {
        let mut cfg = NodeConfig::new(ns, "csba-wls+".parse().unwrap());
        cfg.max_wait_ms = max_wait_ms;
        spawn_fuser_with(session, cfg)
    }

    /// Starts a fuser node that reports fused windows on a channel; returns (stop, reports, task).
    pub fn spawn_fuser_with(session: zenoh::Session, cfg: NodeConfig) -> FuserHandle {
        let (tx, rx) = mpsc::unbounded_channel();
        let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
        let task = tokio::spawn(async move {
            let stats = node::run(&session, cfg, |f| tx.send(f.clone()).unwrap(), async {
                let _ = stop_rx.await;
            })
            .await
            .unwrap();
            session.close().await.unwrap();
            stats
        });
        (stop_tx, rx, task)
    }

    /// Waits (20 s at most) until the fuser's stats list exactly these live agents.
    pub async fn wait_live(session: &zenoh::Session, ns: &str, want: &[&str]) {
        let want: BTreeSet<String> = want.iter().map(|s| s.to_string()).collect();
        within(20, &format!("fuser sees live agents {want:?}"), async {
            loop {
                if let Ok(v) = node::query_stats(session, ns, Duration::from_secs(2)).await {
                    let live: BTreeSet<String> = v["live"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|x| x.as_str().unwrap().to_string())
                        .collect();
                    if live == want {
                        return;
                    }
                }
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
        })
        .await
    }

    /// Waits (10 s at most) until a subscriber (the fuser) matches `publisher`.
    pub async fn wait_matching(publisher: &zenoh::pubsub::Publisher<'_>) {
        within(10, "a subscriber", async {
            while !publisher.matching_status().await.unwrap().matching() {
                tokio::time::sleep(Duration::from_millis(10)).await;
            }
        })
        .await
    }

    /// The fuser's statistics as `v2x-fuser stats` prints them (10 s at most).
    pub async fn stats(session: &zenoh::Session, ns: &str) -> serde_json::Value {
        within(
            10,
            "stats",
            node::query_stats(session, ns, Duration::from_secs(5)),
        )
        .await
        .expect("the fuser answers")
    }

    /// The next fused window (10 s at most).
    pub async fn next_fused(rx: &mut mpsc::UnboundedReceiver<Fused>) -> Fused {
        within(10, "a fused window", rx.recv())
            .await
            .expect("fuser running")
    }
}
