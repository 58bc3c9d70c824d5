//! Replays the fuzz targets' minimized corpus and every input that once failed
//! (`fuzz/corpus/TARGET`, `fuzz/regressions/TARGET`) through the properties they check, so
//! `cargo test` keeps what the fuzzer found fixed.

use std::path::PathBuf;

fn inputs(target: &str) -> Vec<(PathBuf, Vec<u8>)> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fuzz");
    let mut out = Vec::new();
    for dir in ["corpus", "regressions"] {
        let Ok(entries) = std::fs::read_dir(root.join(dir).join(target)) else {
            continue;
        };
        for e in entries {
            let p = e.unwrap().path();
            out.push((p.clone(), std::fs::read(&p).unwrap()));
        }
    }
    assert!(!out.is_empty(), "no corpus for {target}");
    out
}

#[test]
fn wire_decode_corpus() {
    for (path, data) in inputs("wire_decode") {
        let r = std::panic::catch_unwind(|| v2x_protocol::fuzzing::wire_round_trip(&data));
        assert!(r.is_ok(), "{}", path.display());
    }
}

#[test]
fn results_json_corpus() {
    for (path, data) in inputs("results_json") {
        let r = std::panic::catch_unwind(|| v2x_protocol::fuzzing::results_round_trip(&data));
        assert!(r.is_ok(), "{}", path.display());
    }
}
