//! The `v2x-fuser` binary: help lists every method, bad input fails with one clear line.
//! (This integration test also makes `cargo test` build the binary the end-to-end tests run.)

use std::process::Command;

#[test]
fn help_lists_methods_and_errors_are_one_line() {
    let exe = env!("CARGO_BIN_EXE_v2x-fuser");
    let out = Command::new(exe).args(["fuse", "--help"]).output().unwrap();
    assert!(out.status.success());
    let help = String::from_utf8(out.stdout).unwrap();
    for (name, _) in v2x_fuser::METHODS {
        assert!(help.contains(name), "{name}");
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
