//! Fuzz target `cpm_decode`: see `v2x_cpm::fuzzing::decode_round_trip` for the property it checks.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    v2x_cpm::fuzzing::decode_round_trip(data);
});
