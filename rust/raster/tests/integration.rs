//! The integration tests of this crate, one module per file beside this one, built as one test
//! binary (one link instead of one per file).

mod gradcheck;
mod raster_basics;
mod toy;
