//! No code. This crate only enables features on shared dependencies (see its Cargo.toml), so that
//! every build of the workspace compiles them the same way.
