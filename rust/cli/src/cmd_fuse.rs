//! `hairrecon fuse-depth`: fuse a capture's depth maps into its raw mesh (TSDF + surface nets).
//!
//! This makes a stand-in for a photogrammetry mesh from depth maps (see
//! `hairrecon_recon::raw_mesh`). The synthetic renderer (`scripts/render_synthetic.py`) calls it
//! with `--depth-dir fusion/depth`, its depth maps of the hair volume.
//!
//! `--check-gt` then measures the mesh against the ground-truth hair that the photographs see
//! (issue 3's criterion, `hairrecon_recon::raw_mesh::check`): ground-truth strand points seen in
//! two or more views by the views' `gt_depth` (the photographs' own depth), their distance to the
//! mesh, unsigned and signed. `--no-fuse --check-gt` measures an existing mesh.

use std::path::PathBuf;
use std::time::Instant;

use hairrecon_recon::progress::Progress;
use hairrecon_recon::raw_mesh::check::{check_seen_hair, CheckOptions};
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
    /// The inset moves no vertex inside the capture's head mesh (head_mesh): the skin, which the
    /// depth maps draw as it is, stays on the head while the hair comes in.
    #[arg(long, requires = "inset_mm")]
    pub inset_above_head: bool,
    /// Fuse each voxel's per-view truncated distances by this quantile (0.5: median) instead of
    /// their mean.
    #[arg(long)]
    pub quantile: Option<f32>,
    /// Folder of depth maps named `<view>.exr`, relative to the capture (default: each view's gt_depth).
    #[arg(long)]
    pub depth_dir: Option<PathBuf>,
    /// Output mesh (.ply or .obj; default: the capture's raw_mesh path).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Afterwards, load the whole capture with the validating loader and fail if it does not load.
    #[arg(long)]
    pub check_capture: bool,
    /// Do not fuse: use the existing mesh (--out, else the capture's raw mesh), e.g. with --check-gt.
    #[arg(long)]
    pub no_fuse: bool,
    /// Afterwards, measure the mesh against the ground-truth strand points seen in the photographs
    /// (gt_strands, and each view's gt_depth) and print the figures.
    #[arg(long)]
    pub check_gt: bool,
    /// --check-gt: a point is seen in a view when its depth is within this of the gt depth map (mm).
    #[arg(long, default_value_t = 1.0)]
    pub check_depth_tol_mm: f32,
    /// --check-gt: count points seen in at least this many views.
    #[arg(long, default_value_t = 2)]
    pub check_min_views: usize,
    /// --check-gt: the distance to the mesh that the criterion counts within (mm).
    #[arg(long, default_value_t = 3.0)]
    pub check_within_mm: f32,
    /// --check-gt: test every this-many-th ground-truth point.
    #[arg(long, default_value_t = 1)]
    pub check_step: usize,
    /// --check-gt: write the seen points as text lines "x y z signed_distance" (metres; + = the
    /// mesh is in front of the point) to this file.
    #[arg(long)]
    pub check_dump: Option<PathBuf>,
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
    let json = if args.capture.is_dir() { args.capture.join("capture.json") } else { args.capture.clone() };
    let spec: hairrecon_core::capture::CaptureSpec = serde_json::from_str(&std::fs::read_to_string(&json)?)?;
    let dir = json.parent().map(PathBuf::from).unwrap_or_default();
    let out = args.out.clone().unwrap_or_else(|| dir.join(&spec.raw_mesh));
    if !args.no_fuse {
        let floor = match (&spec.head_mesh, args.inset_above_head) {
            (Some(head), true) => Some(dir.join(head)),
            (None, true) => return Err("--inset-above-head: the capture names no head_mesh".into()),
            (_, false) => None,
        };
        fuse(&args, &out, floor.as_deref())?;
    }
    if args.check_capture {
        let c = hairrecon_core::capture::Capture::load(&args.capture)?;
        eprintln!("fuse-depth: the capture loads: {} views, raw mesh {}", c.views.len(), c.raw_mesh.display());
    }
    if args.check_gt {
        let gt = spec.gt_strands.as_ref().ok_or("--check-gt: the capture names no gt_strands")?;
        check_gt(&args, &out, &dir.join(gt))?;
    }
    Ok(())
}

/// Measures the mesh at `mesh` against the ground-truth points seen in the photographs.
fn check_gt(args: &FuseDepthArgs, mesh: &std::path::Path, gt: &std::path::Path) -> CmdResult {
    use std::io::Write;
    let t0 = Instant::now();
    let mesh = hairrecon_core::read_mesh(mesh)?;
    let strands = hairrecon_core::read_strands(gt)?;
    let points: Vec<_> = strands.points().iter().step_by(args.check_step.max(1)).copied().collect();
    let views: Vec<_> = raw_mesh::load_depth_views(&args.capture, None)?.into_iter().map(|(_, v)| v).collect();
    let opts = CheckOptions {
        depth_tolerance: args.check_depth_tol_mm * 1e-3,
        min_views: args.check_min_views,
        within: args.check_within_mm * 1e-3,
    };
    let (report, per_point) = check_seen_hair(&mesh, &points, &views, &opts);
    eprintln!("check-gt: {report} ({:.1} s)", t0.elapsed().as_secs_f32());
    if let Some(path) = &args.check_dump {
        let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
        for (i, d) in per_point {
            let p = points[i];
            writeln!(w, "{} {} {} {}", p.x, p.y, p.z, d)?;
        }
        w.flush()?;
    }
    Ok(())
}

fn fuse(args: &FuseDepthArgs, out: &std::path::Path, floor: Option<&std::path::Path>) -> CmdResult {
    let t0 = Instant::now();
    let views = raw_mesh::load_depth_views(&args.capture, args.depth_dir.as_deref())?;
    let opts = FuseOptions {
        voxel: args.voxel_mm * 1e-3,
        truncation_voxels: args.truncation_voxels,
        smooth_iterations: args.smooth,
        min_component_triangles: args.min_component,
        // with a floor, the inset is made after fusing, vertex by vertex
        inset: if floor.is_some() { 0.0 } else { args.inset_mm * 1e-3 },
        quantile: args.quantile,
        ..FuseOptions::default()
    };
    let depth: Vec<_> = views.into_iter().map(|(_, v)| v).collect();
    let bar = crate::progress::bar(1000, "tsdf");
    let progress = BarProgress(bar);
    let mut mesh = raw_mesh::fuse_depth_maps(&depth, &opts, &progress)?;
    progress.0.finish_and_clear();
    if let Some(floor) = floor {
        let head =
            hairrecon_core::read_mesh(floor).map_err(|e| format!("--inset-above-head: {}: {e}", floor.display()))?;
        raw_mesh::inset_above(&mut mesh, args.inset_mm * 1e-3, &hairrecon_core::mesh::Bvh::new(head));
    }
    hairrecon_core::formats::write_mesh(out, &mesh)?;
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
    Ok(())
}
