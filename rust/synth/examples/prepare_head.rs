//! Writes the head fixtures: `cargo run -p hairrecon-synth --example prepare_head [SOURCE] [OUT_DIR]`.
//!
//! SOURCE defaults to /work/shared/data/heads/woman_head.ply (its sha256 is checked), OUT_DIR to the
//! repository's blend_fixtures/.

use std::path::PathBuf;

fn main() {
    let mut args = std::env::args().skip(1);
    let source = args.next().map(PathBuf::from).unwrap_or_else(|| "/work/shared/data/heads/woman_head.ply".into());
    let out = args.next().map(PathBuf::from).unwrap_or_else(hairrecon_synth::fixtures_dir);
    match hairrecon_synth::head::prepare_fixtures(&source, &out) {
        Ok(s) => {
            println!("head:  {} ({} vertices, {} triangles)", s.head.display(), s.head_vertices, s.head_triangles);
            println!("       bbox {:?} .. {:?} m", s.bbox.0, s.bbox.1);
            println!(
                "scalp: {} ({} vertices, {} triangles, {:.4} m²)",
                s.scalp.display(),
                s.scalp_vertices,
                s.scalp_triangles,
                s.scalp_area
            );
            println!("mask:  {}", s.mask.display());
        }
        Err(e) => {
            eprintln!("prepare_head: error: {e}");
            std::process::exit(1);
        }
    }
}
