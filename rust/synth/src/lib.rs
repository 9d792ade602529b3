//! hairrecon-synth: synthetic ground truth on the bundled head.
//!
//! - [`head`]: the head fixture, Cem Yuksel's woman head normalised to metres, Z up, face toward −Y.
//! - [`scalp_region`]: the rule that defines the scalp on that head, its submesh and UV mask.
//! - [`collide`]: keeping points outside the head (signed distance with an offset).
//! - [`style`]: the hairstyle presets (straight, wavy, curly, short, bob, volume, and the held-out
//!   side_part, layered, spiky, ponytail, coils, loose_curls, coarse).
//! - [`mod@generate`]: the seeded, parallel strand generator.
//! - [`preview`]: front/side/back pictures of a hairstyle on the head.
//!
//! The scalp's growth direction S(p_s) and the blue-noise root sampler live in
//! [`hairrecon_core::scalp`], so that reconstruction uses the same definitions.

pub mod collide;
pub mod error;
pub mod generate;
pub mod head;
pub mod preview;
pub mod scalp_region;
pub mod style;

pub use error::SynthError;
pub use generate::{generate, HairGenerator, SynthOptions, DEFAULT_POINTS, DEFAULT_STRANDS};
pub use style::{Style, StyleParams};

use std::path::{Path, PathBuf};

/// The folder of the bundled fixtures, `blend_fixtures/` at the root of the repository.
pub fn fixtures_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../blend_fixtures")
}
