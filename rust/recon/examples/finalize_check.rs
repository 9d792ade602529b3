//! What the DR's finalization (roots onto the scalp, even segments, points out of the head) does to
//! a strand set on its own: writes `OUT/{none,even,head,both}.hair` from `STRANDS` (every `EVERY`-th
//! strand) for scoring with `hairrecon eval`.
//!
//! `cargo run --release -p hairrecon-recon --example finalize_check -- CAPTURE STRANDS OUT [EVERY]`

use hairrecon_core::capture::Capture;
use hairrecon_core::formats::{read_mesh, read_strands, write_strands};
use hairrecon_core::Bvh;
use hairrecon_recon::dr::finalize;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        eprintln!("usage: finalize_check CAPTURE STRANDS OUT [EVERY]");
        std::process::exit(2);
    }
    let capture = Capture::load(&args[0])?;
    let every: usize = args.get(3).map(|s| s.parse()).transpose()?.unwrap_or(1);
    let all = read_strands(&args[1])?;
    let set = all.select(&(0..all.num_strands()).step_by(every.max(1)).collect::<Vec<_>>());
    let out = std::path::PathBuf::from(&args[2]);
    std::fs::create_dir_all(&out)?;
    let scalp = Bvh::new(read_mesh(capture.scalp_mesh.as_ref().ok_or("no scalp mesh")?)?);
    let head = capture.head_mesh.as_ref().map(read_mesh).transpose()?.map(Bvh::new);
    let clearance = 0.001;
    write_strands(out.join("none.hair"), &set)?;
    write_strands(out.join("even.hair"), &finalize(&set, &scalp, None, clearance, true))?;
    write_strands(out.join("head.hair"), &finalize(&set, &scalp, head.as_ref(), clearance, false))?;
    write_strands(out.join("both.hair"), &finalize(&set, &scalp, head.as_ref(), clearance, true))?;
    Ok(())
}
