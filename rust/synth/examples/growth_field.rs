//! Draws S(p_s) on the bundled scalp: `cargo run -p hairrecon-synth --example growth_field [OUT.png]`.
//!
//! 3,000 blue-noise roots, each with a 12 mm segment along its growth direction, in the front, side
//! and back views of [`hairrecon_synth::preview`]. Default output: docs/images/synth_growth_field.png.

use hairrecon_core::formats::read_mesh;
use hairrecon_core::scalp::Scalp;
use hairrecon_core::StrandSet;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args().nth(1).unwrap_or_else(|| {
        hairrecon_synth::fixtures_dir().join("../docs/images/synth_growth_field.png").display().to_string()
    });
    let dir = hairrecon_synth::fixtures_dir();
    let head = read_mesh(dir.join("head.ply"))?;
    let scalp = Scalp::new(read_mesh(dir.join("scalp.ply"))?)?;
    let roots = scalp.sample_roots(3000, 1)?;
    let points: Vec<_> = roots.iter().flat_map(|r| [r.position, r.position + 0.012 * r.direction]).collect();
    let strands = StrandSet::new(points, vec![2; roots.len()])?;
    hairrecon_synth::preview::render_preview(&head, &strands, 500).save(&out)?;
    println!("{out}: whorl at {:?}", scalp.field().whorl);
    Ok(())
}
