//! hairrecon-recon.
