//! The integration tests of this crate, one module per file beside this one, built as one test
//! binary (one link instead of one per file).
//! Alone in their own binaries, as they act on the whole process: `stage_clock.rs` (the process's CPU time)
//! and `pipeline_synthetic.rs` (the process's peak memory at each stage).

mod common;
mod dr;
mod head_fit;
mod head_shape;
mod laplace_columns;
mod pipeline_dr;
mod resume;
