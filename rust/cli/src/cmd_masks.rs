//! `hairrecon masks`: hair masks of every view of a capture, without ground truth
//! (`hairrecon_recon::masks`): the hair region of the raw mesh, its silhouette in each view, and
//! matting against the photo. The capture needs a head and a scalp (`hairrecon fit-head --write`
//! makes them). Prints a JSON report on stdout.
//!
//! `--write` puts the masks into the capture for the views that have none (a user's own masks are
//! kept) with `hair_region.ply` and `masks.json`; `--out DIR` writes them into DIR instead, for a
//! look. `--score` compares them with the capture's own masks (a synthetic capture's ground
//! truth); `--gt-masks DIR` with `DIR/<view>.png`, area-averaged to the view's size (a wild
//! capture's `gt/masks`, at the photos' size).

use std::path::{Path, PathBuf};
use std::time::Instant;

use hairrecon_core::capture::{Capture, CaptureSpec};
use hairrecon_recon::masks::capture_masks::{report, write_folder, write_into_capture};
use hairrecon_recon::masks::quality::score_views;
use hairrecon_recon::masks::{make_masks, MaskError, MaskOptions};

use crate::progress::Bars;
use crate::CmdResult;

#[derive(Debug, clap::Args)]
pub struct MasksArgs {
    /// Capture folder (or its capture.json), with a head and a scalp.
    pub capture: PathBuf,
    /// Write the masks into the capture (views without a mask) and name them in capture.json.
    #[arg(long, conflicts_with = "out")]
    pub write: bool,
    /// Write the masks into this folder (masks/VIEW.png, hair_region.ply, masks.json).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Score the masks against the capture's own (a synthetic capture's ground truth).
    #[arg(long, conflicts_with = "gt_masks")]
    pub score: bool,
    /// Score the masks against DIR/VIEW.png (at the view's size or larger: area-averaged to it).
    #[arg(long)]
    pub gt_masks: Option<PathBuf>,
    /// Keep the silhouette's hard edge (no matting).
    #[arg(long)]
    pub no_matting: bool,
    /// Half-width of the trimap's unknown band, in millimetres at the head's distance.
    #[arg(long, default_value_t = MaskOptions::default().band_mm)]
    pub band_mm: f32,
    /// Weight of each pixel's own colour against the hair region's probability.
    #[arg(long, default_value_t = MaskOptions::default().pixel_colour)]
    pub pixel_colour: f32,
    /// Through a hole of the raw mesh onto the fitted scalp, take the hair region of the raw
    /// mesh's closest point within this many millimetres; 0 turns it off.
    #[arg(long, default_value_t = MaskOptions::default().hole_mm)]
    pub hole_mm: f32,
    /// Averaging passes of the hair probability over the raw mesh.
    #[arg(long, default_value_t = MaskOptions::default().region.smoothing)]
    pub smoothing: usize,
    /// How far beyond the silhouette (mm at the head's distance) to look for hair the raw mesh
    /// left out, in the photo's blend of hair and what lies behind; 0 turns it off.
    #[arg(long, default_value_t = MaskOptions::default().beyond.reach_mm)]
    pub beyond_mm: f32,
}

pub fn run(args: MasksArgs) -> CmdResult {
    let t0 = Instant::now();
    let json_path = CaptureSpec::json_path(&args.capture);
    let capture = Capture::load(&json_path)?;
    let spec = read_spec(&json_path)?;
    let given: Vec<Option<PathBuf>> = capture.views.iter().map(|v| v.mask.clone()).collect();
    let working = capture.in_canonical_frame()?.ok_or_else(|| {
        format!(
            "{}: the capture is in an imported frame with no to_canonical; run `hairrecon fit-head {} --write` first",
            json_path.display(),
            args.capture.display()
        )
    })?;
    let mut opts = MaskOptions {
        matting: !args.no_matting,
        band_mm: args.band_mm,
        pixel_colour: args.pixel_colour,
        hole_mm: args.hole_mm,
        ..MaskOptions::default()
    };
    opts.region.smoothing = args.smoothing;
    opts.beyond.reach_mm = args.beyond_mm;
    let bars = Bars::new();
    let set = make_masks(&working, &opts, &bars);
    bars.finish();
    if matches!(set, Err(MaskError::Cancelled(_))) && bars.interrupt.requested() {
        bars.interrupt.exit("no masks were written");
    }
    let set = set?;
    let names: Vec<String> = capture.views.iter().map(|v| v.name.clone()).collect();
    let scores = if args.score {
        Some(score_views(&set.alphas, &names, &given)?)
    } else if let Some(dir) = &args.gt_masks {
        let paths: Vec<Option<PathBuf>> = names.iter().map(|n| Some(dir.join(format!("{n}.png")))).collect();
        Some(score_views(&set.alphas, &names, &paths)?)
    } else {
        None
    };
    let report = report(&set, &names, scores.as_deref(), &opts, t0.elapsed().as_secs_f64());
    let text = serde_json::to_string_pretty(&report)?;
    if args.write {
        write_into_capture(&json_path, &spec, &set, &text)?;
    } else if let Some(out) = &args.out {
        write_folder(out, &names, &set, &capture.raw_mesh, &text)?;
    }
    println!("{text}");
    Ok(())
}

fn read_spec(json_path: &Path) -> Result<CaptureSpec, Box<dyn std::error::Error + Send + Sync>> {
    let text = std::fs::read_to_string(json_path).map_err(|e| format!("cannot read {}: {e}", json_path.display()))?;
    Ok(CaptureSpec::from_json(serde_json::from_str(&text)?, json_path)?)
}
