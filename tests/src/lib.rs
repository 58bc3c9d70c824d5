//! Helpers for the end-to-end tests in `tests/tests/`: locating the workspace's binaries,
//! building small scenarios, and waiting with a timeout.

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
