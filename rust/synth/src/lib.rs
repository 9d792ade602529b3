//! hairrecon-synth.
