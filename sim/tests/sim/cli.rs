//! The `v2x-sim` binary: help names every subcommand, bad input fails with one clear line.
//! (This integration test also makes `cargo test` build the binary the end-to-end tests run.)

use std::process::Command;

#[test]
fn help_and_clear_errors() {
    let exe = env!("CARGO_BIN_EXE_v2x-sim");
    let out = Command::new(exe).arg("--help").output().unwrap();
    assert!(out.status.success());
    let help = String::from_utf8(out.stdout).unwrap();
    for cmd in ["gen", "eval", "bench", "plot", "run", "load"] {
        assert!(help.contains(cmd), "{cmd}");
    }
    let out = Command::new(exe)
        .args(["bench", "--dataroot", "/nonexistent", "--version", "v1.0-x"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(
        err.starts_with("error: /nonexistent/v1.0-x: no such directory"),
        "{err}"
    );
    let out = Command::new(exe)
        .args(["run", "--role", "ghost"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(
        err.contains("--role ghost: not a role of this scenario (roles: fuser, veh, rsu)"),
        "{err}"
    );
}
