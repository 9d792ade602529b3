//! `hairrecon fuse-depth`: fuse a capture's depth maps into its raw mesh (TSDF + surface nets).
//!
//! This makes a stand-in for a photogrammetry mesh from depth maps (see
//! `hairrecon_recon::raw_mesh`). The synthetic renderer (`scripts/render_synthetic.py`) calls it
//! with `--depth-dir fusion/depth`, its depth maps of the hair volume.

use std::path::PathBuf;
use std::time::Instant;

use hairrecon_recon::progress::Progress;
use hairrecon_recon::raw_mesh::{self, FuseOptions};
use indicatif::ProgressBar;

use crate::CmdResult;

#[derive(Debug, clap::Args)]
pub struct FuseDepthArgs {
    /// Capture folder (or its capture.json). Its raw mesh need not exist yet.
    pub capture: PathBuf,
    /// Voxel size in millimetres.
    #[arg(long, default_value_t = 2.0)]
    pub voxel_mm: f32,
    /// Truncation distance in voxels.
    #[arg(long, default_value_t = 3.0)]
    pub truncation_voxels: f32,
    /// Pairs of Taubin smoothing steps (0: no smoothing).
    #[arg(long, default_value_t = 3)]
    pub smooth: u32,
    /// Drop connected pieces with fewer triangles than this.
    #[arg(long, default_value_t = 200)]
    pub min_component: usize,
    /// Move the surface inward by this many millimetres (for depth maps that show strands wider
    /// than they are, like the synthetic renderer's fusion depth maps).
    #[arg(long, default_value_t = 0.0)]
    pub inset_mm: f32,
    /// Folder of depth maps named <view>.exr, relative to the capture (default: each view's gt_depth).
    #[arg(long)]
    pub depth_dir: Option<PathBuf>,
    /// Output mesh (.ply or .obj; default: the capture's raw_mesh path).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Afterwards, load the whole capture with the validating loader and fail if it does not load.
    #[arg(long)]
    pub check_capture: bool,
}

/// Shows a stage's progress on an indicatif bar (per mille).
struct BarProgress(ProgressBar);

impl Progress for BarProgress {
    fn update(&self, stage: &str, fraction: f32, message: &str) {
        self.0.set_prefix(stage.to_string());
        self.0.set_position((fraction.clamp(0.0, 1.0) * 1000.0) as u64);
        self.0.set_message(message.to_string());
    }
}

pub fn run(args: FuseDepthArgs) -> CmdResult {
    let t0 = Instant::now();
    let views = raw_mesh::load_depth_views(&args.capture, args.depth_dir.as_deref())?;
    let out = match args.out {
        Some(p) => p,
        None => {
            let json = if args.capture.is_dir() { args.capture.join("capture.json") } else { args.capture.clone() };
            let spec: hairrecon_core::capture::CaptureSpec = serde_json::from_str(&std::fs::read_to_string(&json)?)?;
            json.parent().map(|d| d.join(&spec.raw_mesh)).unwrap_or(spec.raw_mesh)
        }
    };
    let opts = FuseOptions {
        voxel: args.voxel_mm * 1e-3,
        truncation_voxels: args.truncation_voxels,
        smooth_iterations: args.smooth,
        min_component_triangles: args.min_component,
        inset: args.inset_mm * 1e-3,
        ..FuseOptions::default()
    };
    let depth: Vec<_> = views.into_iter().map(|(_, v)| v).collect();
    let bar = crate::progress::bar(1000, "tsdf");
    let progress = BarProgress(bar);
    let mesh = raw_mesh::fuse_depth_maps(&depth, &opts, &progress)?;
    progress.0.finish_and_clear();
    hairrecon_core::formats::write_mesh(&out, &mesh)?;
    let (lo, hi) = mesh.bbox();
    eprintln!(
        "fuse-depth: {} views, {} vertices, {} triangles, box {:.3?}..{:.3?} m, {:.1} s -> {}",
        depth.len(),
        mesh.vertices.len(),
        mesh.triangles.len(),
        lo.to_array(),
        hi.to_array(),
        t0.elapsed().as_secs_f32(),
        out.display()
    );
    if args.check_capture {
        let c = hairrecon_core::capture::Capture::load(&args.capture)?;
        eprintln!("fuse-depth: the capture loads: {} views, raw mesh {}", c.views.len(), c.raw_mesh.display());
    }
    Ok(())
}
