//! The fuser's command line, its fuzz corpus and its MCAP output, in one test binary.

mod cli;
mod fuzz_corpus;
mod viz;
