//! The integration tests of this crate, one module per file beside this one, built as one test
//! binary (one link instead of one per file).
//! Alone in their own binaries, as they act on the whole process: `temporaries.rs`.

mod formats_corruption;
mod formats_image;
mod formats_mesh;
mod formats_strands;
