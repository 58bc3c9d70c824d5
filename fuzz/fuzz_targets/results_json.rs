//! Fuzz target `results_json`: see `v2x_protocol::fuzzing::results_round_trip` for the property it checks.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    v2x_protocol::fuzzing::results_round_trip(data);
});
