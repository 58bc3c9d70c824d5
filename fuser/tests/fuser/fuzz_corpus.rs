//! Replays the `window` fuzz target's minimized corpus and every input that once failed
//! (`fuzz/corpus/window`, `fuzz/regressions/window`) through the invariants it checks.

use std::path::PathBuf;

#[test]
fn window_corpus() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fuzz");
    let mut n = 0;
    for dir in ["corpus", "regressions"] {
        let Ok(entries) = std::fs::read_dir(root.join(dir).join("window")) else {
            continue;
        };
        for e in entries {
            let p = e.unwrap().path();
            let data = std::fs::read(&p).unwrap();
            let r = std::panic::catch_unwind(|| v2x_fuser::fuzzing::window_events(&data));
            assert!(r.is_ok(), "{}", p.display());
            n += 1;
        }
    }
    assert!(n > 0, "no corpus for the window target");
}
