//! Raw mesh fusion (not built yet).
