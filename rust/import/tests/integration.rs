//! The integration tests of this crate, one module per file beside this one, built as one test
//! binary (one link instead of one per file).

mod conventions;
mod errors;
mod import_capture;
mod photo;
mod roundtrip;
