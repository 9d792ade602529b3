//! The integration tests of this crate, one module per file beside this one, built as one test
//! binary (one link instead of one per file).

#[path = "../../recon/tests/common/mod.rs"]
mod common;
mod eval_cli;
mod fit_head_cli;
mod import_cli;
mod interrupt_cli;
mod masks_cli;
mod reconstruct_cli;
