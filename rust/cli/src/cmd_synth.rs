//! `hairrecon synth-hair`: a synthetic hairstyle on the bundled head, written as a strand file.

use std::path::{Path, PathBuf};
use std::time::Instant;

use hairrecon_core::formats::{read_mesh, write_strands};
use hairrecon_synth::{HairGenerator, Style, SynthError, SynthOptions, DEFAULT_POINTS, DEFAULT_STRANDS};

use crate::CmdResult;

#[derive(Debug, clap::Args)]
pub struct SynthHairArgs {
    /// Hairstyle: straight, wavy, curly, short, bob, volume (the tuning styles), side_part, layered,
    /// spiky, ponytail, coils, loose_curls or coarse (held out for reporting).
    #[arg(long, default_value = "straight")]
    pub style: String,
    /// Number of strands.
    #[arg(long, default_value_t = DEFAULT_STRANDS)]
    pub strands: usize,
    /// Points per strand (root and tip included).
    #[arg(long, default_value_t = DEFAULT_POINTS)]
    pub points: usize,
    /// Random seed: the same seed gives the same file.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output strand file (.hair, .data, .ply or .obj, by extension).
    #[arg(long)]
    pub out: PathBuf,
    /// Head mesh in metres, Z up, face toward -Y [default: blend_fixtures/head.ply of the repository].
    #[arg(long)]
    pub head: Option<PathBuf>,
    /// Scalp mesh (where roots grow) [default: blend_fixtures/scalp.ply of the repository].
    #[arg(long)]
    pub scalp: Option<PathBuf>,
    /// Also write a PNG with front, side and back views of the hair on the head.
    #[arg(long)]
    pub preview: Option<PathBuf>,
    /// Curls of round helices instead of the style's own: RADIUS_MM,PERIOD_MM (e.g. 4.5,16; the
    /// curly style's are 6.5,22). For making captures with other curls than the preset's.
    #[arg(long, value_parser = parse_curl)]
    pub curl: Option<(f32, f32)>,
}

/// `RADIUS_MM,PERIOD_MM` in metres.
fn parse_curl(s: &str) -> Result<(f32, f32), String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("curl {s:?}: give RADIUS_MM,PERIOD_MM (e.g. 4.5,16)"))?;
    match v[..] {
        [r, p] if r > 0.0 && r < 100.0 && p > 0.0 && p < 1000.0 => Ok((r / 1000.0, p / 1000.0)),
        _ => Err(format!("curl {s:?}: give RADIUS_MM,PERIOD_MM with a radius in (0, 100) and a period in (0, 1000)")),
    }
}

/// A fixture given on the command line, else `blend_fixtures/<name>` in the working directory or
/// one of its parents, else in the repository this binary was built from.
fn fixture(given: Option<PathBuf>, name: &str, what: &'static str) -> Result<PathBuf, SynthError> {
    let hint = "pass its path, or run from the repository (blend_fixtures/); \
                `cargo run -p hairrecon-synth --example prepare_head` remakes the fixtures";
    if let Some(p) = given {
        return if p.is_file() { Ok(p) } else { Err(SynthError::MissingFile { what, path: p, hint }) };
    }
    let rel = Path::new("blend_fixtures").join(name);
    if let Ok(cwd) = std::env::current_dir() {
        for dir in cwd.ancestors() {
            if dir.join(&rel).is_file() {
                return Ok(dir.join(&rel));
            }
        }
    }
    let built = hairrecon_synth::fixtures_dir().join(name);
    if built.is_file() {
        return Ok(built);
    }
    Err(SynthError::MissingFile { what, path: rel, hint })
}

pub fn run(args: SynthHairArgs) -> CmdResult {
    let style: Style = args.style.parse()?;
    let head_path = fixture(args.head, "head.ply", "head mesh")?;
    let scalp_path = fixture(args.scalp, "scalp.ply", "scalp mesh")?;
    let mut opts =
        SynthOptions { strands: args.strands, points: args.points, seed: args.seed, ..SynthOptions::new(style) };
    if let Some((radius, period)) = args.curl {
        opts.params.curl_radius = [radius, radius];
        opts.params.curl_period = period;
    }
    let start = Instant::now();
    let head = read_mesh(&head_path)?;
    let scalp = read_mesh(&scalp_path)?;
    let gen = HairGenerator::new(&head, scalp)?;
    let bar = crate::progress::bar(args.strands as u64, "synth-hair");
    let strands = gen.generate(&opts, &|done| bar.set_position(done as u64))?;
    bar.finish_and_clear();
    let generated = start.elapsed();
    write_strands(&args.out, &strands)?;
    let stats = strands.length_stats();
    eprintln!(
        "{}: {} strands x {} points, style {}, seed {}; generated in {:.2} s",
        args.out.display(),
        strands.num_strands(),
        args.points,
        style,
        args.seed,
        generated.as_secs_f64()
    );
    if let Some(s) = stats {
        eprintln!("strand length (m): min {:.3} median {:.3} mean {:.3} max {:.3}", s.min, s.median, s.mean, s.max);
    }
    if let Some(png) = args.preview {
        let img = hairrecon_synth::preview::render_preview(&head, &strands, 600);
        img.save(&png).map_err(|e| SynthError::Image { path: png.clone(), source: e })?;
        eprintln!("preview: {}", png.display());
    }
    Ok(())
}
