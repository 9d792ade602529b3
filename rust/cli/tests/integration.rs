//! The integration tests of this crate, one module per file beside this one, built as one test
//! binary (one link instead of one per file). Alone in its own binary: `interrupt_cli.rs`, whose signals
//! land at moments timed from a whole run, which other tests running beside it would slow.

#[path = "../../recon/tests/common/mod.rs"]
mod common;
mod eval_cli;
mod fit_head_cli;
mod import_cli;
mod masks_cli;
mod reconstruct_cli;
