//! The `v2x-agent` binary: help, and a clear error for a file it cannot read.
//! (This integration test also makes `cargo test` build the binary the end-to-end tests run.)

use std::process::Command;

#[test]
fn help_and_clear_errors() {
    let exe = env!("CARGO_BIN_EXE_v2x-agent");
    let out = Command::new(exe).arg("--help").output().unwrap();
    assert!(out.status.success());
    let help = String::from_utf8(out.stdout).unwrap();
    for flag in [
        "--latency-ms",
        "--drop-rate",
        "--clock-offset-ms",
        "--connect",
        "--no-multicast-scouting",
    ] {
        assert!(help.contains(flag), "{flag}");
    }
    let out = Command::new(exe)
        .args(["/nonexistent/a.json", "--name", "veh"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(
        err.starts_with("error: /nonexistent/a.json: cannot read"),
        "{err}"
    );
}
