//! Fuzz target `wire_decode`: see `v2x_protocol::fuzzing::wire_round_trip` for the property it checks.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    v2x_protocol::fuzzing::wire_round_trip(data);
});
