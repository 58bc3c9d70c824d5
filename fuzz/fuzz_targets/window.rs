//! Fuzz target `window`: see `v2x_fuser::fuzzing::window_events` for the property it checks.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    v2x_fuser::fuzzing::window_events(data);
});
