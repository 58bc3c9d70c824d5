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
