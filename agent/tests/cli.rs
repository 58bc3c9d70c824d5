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
        "--link",
        "--connect",
        "--no-multicast-scouting",
        "--wire",
        "--ros-topic",
        "--tf",
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
    // A ROS topic that is not one, a transform that is not four numbers, a file and a topic.
    let run = |args: &[&str]| {
        let out = Command::new(exe).args(args).output().unwrap();
        assert!(!out.status.success(), "{args:?}");
        String::from_utf8(out.stderr).unwrap()
    };
    let err = run(&[
        "--ros-topic",
        "/a//b",
        "--name",
        "veh",
        "--no-multicast-scouting",
    ]);
    assert!(err.contains("'/a//b' is not a ROS 2 topic name"), "{err}");
    let err = run(&["a.json", "--name", "veh", "--ns", "a/b"]);
    assert!(err.contains("namespace 'a/b' contains '/'"), "{err}");
    let err = run(&["a.json", "--name", "veh", "--link", "latency_ms=-5"]);
    assert!(err.contains("latency_ms"), "{err}");
    let err = run(&["a.json", "--name", "veh", "--link", "latency=5"]);
    assert!(
        err.contains("unknown field `latency`, expected one of `latency_ms`"),
        "{err}"
    );
    let err = run(&["--ros-topic", "/a", "--tf", "1,2,3", "--name", "veh"]);
    assert!(err.contains("X,Y,Z,YAW_DEG"), "{err}");
    let err = run(&["a.json", "--ros-topic", "/a", "--name", "veh"]);
    assert!(err.contains("cannot be used with"), "{err}");
    let dir = std::env::temp_dir().join(format!("v2x-agent-tf-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let tf = dir.join("tf.json");
    std::fs::write(&tf, r#"{"translation": [1, 2], "rotation": [0, 0, 0, 1]}"#).unwrap();
    let err = run(&[
        "--ros-topic",
        "/a",
        "--tf",
        tf.to_str().unwrap(),
        "--name",
        "veh",
    ]);
    assert!(err.contains("`translation` must be 3 numbers"), "{err}");
    let err = run(&["--name", "veh", "--map-origin", "95,0"]);
    assert!(
        err.contains("latitude must be a number of degrees within +-90 (got 95)"),
        "{err}"
    );
}
