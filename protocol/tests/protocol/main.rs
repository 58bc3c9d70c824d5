//! The protocol's fuzz corpus and the wire-format document's examples, in one test binary.

mod fuzz_corpus;
mod wire_doc;
