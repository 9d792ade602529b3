//! `hairrecon eval`, `convert` and `info`: the strand metric and strand file tools.

use std::path::{Path, PathBuf};

use hairrecon_core::capture::FrameSpec;
use hairrecon_core::formats::{read_mesh, read_strands, write_strands};
use hairrecon_core::layer_height::{compare, LayerHeights};
use hairrecon_core::metric::{evaluate, MetricOptions};
use hairrecon_core::similarity::{transform_mesh, transform_strands, Similarity};
use hairrecon_core::Bvh;

use crate::CmdResult;

#[derive(Debug, clap::Args)]
pub struct EvalArgs {
    /// Predicted strands (.hair, .data, .ply or .obj), in metres (or in the frame of --frame).
    #[arg(long)]
    pred: PathBuf,
    /// Ground-truth strands, in metres (or in the frame of --frame).
    #[arg(long)]
    gt: PathBuf,
    /// Both strand sets are in another frame: this JSON file's similarity
    /// (`{"scale", "rotation" (3 × 3 by rows), "translation"}`, as capture.json's `to_canonical`)
    /// maps them to metres before scoring, so that the thresholds are millimetres.
    #[arg(long, value_name = "FRAME.json")]
    frame: Option<PathBuf>,
    /// Arc-length resampling step in millimetres.
    #[arg(long, default_value_t = 1.0)]
    step_mm: f32,
    /// The scalp mesh (in the strands' frame): also compare how far the hair stands off it over the
    /// crown, per 1 cm cell (the median height of the points above it), prediction against ground truth.
    #[arg(long, value_name = "SCALP.ply")]
    scalp: Option<PathBuf>,
    /// Print exactly one JSON object on stdout instead of the table.
    #[arg(long)]
    json: bool,
}

#[derive(Debug, clap::Args)]
pub struct ConvertArgs {
    /// Input strand file (.hair, .data, .ply, .obj).
    input: PathBuf,
    /// Output strand file; the format follows the extension.
    output: PathBuf,
    /// Multiply every coordinate by this factor (e.g. 0.01 for centimetres to metres).
    #[arg(long, default_value_t = 1.0)]
    scale: f32,
}

#[derive(Debug, clap::Args)]
pub struct InfoArgs {
    /// Strand file (.hair, .data, .ply, .obj).
    file: PathBuf,
}

pub fn eval(a: EvalArgs) -> CmdResult {
    if !(a.step_mm.is_finite() && a.step_mm > 0.0) {
        return Err(format!("--step-mm must be a positive number of millimetres, got {}", a.step_mm).into());
    }
    let mut pred = read_strands(&a.pred)?;
    let mut gt = read_strands(&a.gt)?;
    for (path, set, side) in [(&a.pred, &pred, "--pred"), (&a.gt, &gt, "--gt")] {
        if set.num_strands() == 0 {
            return Err(format!(
                "{side} {} holds no strands: there is nothing to score (a score of 0 would hide it); \
                 check that the run that wrote it finished (its report.json)",
                path.display()
            )
            .into());
        }
    }
    if let Some(path) = &a.frame {
        let s = read_frame(path)?;
        pred = transform_strands(&pred, &s).map_err(|e| format!("{}: {e}", a.pred.display()))?;
        gt = transform_strands(&gt, &s).map_err(|e| format!("{}: {e}", a.gt.display()))?;
    }
    let opts = MetricOptions { step: a.step_mm * 1e-3, ..MetricOptions::default() };
    let report = evaluate(&pred, &gt, &opts)?;
    let height = match &a.scalp {
        Some(path) => {
            let mut mesh = read_mesh(path)?;
            if let Some(frame) = &a.frame {
                mesh = transform_mesh(&mesh, &read_frame(frame)?);
            }
            let scalp = Bvh::new(mesh);
            let heights = |s| LayerHeights::measure(s, &scalp, opts.step);
            let c = compare(&heights(&pred)?, &heights(&gt)?);
            Some(c.ok_or_else(|| {
                format!(
                    "--scalp {}: no 1 cm cell of the crown holds 20 points of both strand sets within 5 cm of \
                     it; is it the scalp of these strands, in their frame (Z up)?",
                    path.display()
                )
            })?)
        }
        None => None,
    };
    if a.json {
        let mut v = serde_json::to_value(&report)?;
        if let (Some(h), Some(obj)) = (&height, v.as_object_mut()) {
            obj.insert("crown_height".into(), serde_json::to_value(h)?);
        }
        println!("{v}");
    } else {
        println!(
            "pred: {} ({} strands)   gt: {} ({} strands)",
            a.pred.display(),
            pred.num_strands(),
            a.gt.display(),
            gt.num_strands()
        );
        print!("{}", report.table());
        if let Some(h) = height {
            println!(
                "height above the scalp over the crown ({} cells of 1 cm): ground truth {:.1} mm, prediction {:.1} mm; \
                 |error| per cell: median {:.1} mm, 90th percentile {:.1} mm",
                h.cells, h.gt_median_mm, h.pred_median_mm, h.median_abs_error_mm, h.p90_abs_error_mm
            );
        }
    }
    Ok(())
}

/// A similarity file for `eval --frame`: capture.json's `to_canonical` layout.
fn read_frame(path: &Path) -> Result<Similarity, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("--frame {}: {e}", path.display()))?;
    let spec: FrameSpec = serde_json::from_str(&text).map_err(|e| {
        format!(
            "--frame {}: {e}; expected {{\"scale\": s, \"rotation\": [[..], [..], [..]] (by rows), \"translation\": [x, y, z]}}",
            path.display()
        )
    })?;
    spec.similarity().ok_or_else(|| {
        format!(
            "--frame {}: not a similarity: the scale must be finite and positive, the rotation orthonormal \
             (within 1e-6) with determinant +1, the translation finite",
            path.display()
        )
    })
}

pub fn convert(a: ConvertArgs) -> CmdResult {
    if !(a.scale.is_finite() && a.scale != 0.0) {
        return Err(format!("--scale must be a finite non-zero number, got {}", a.scale).into());
    }
    let s = read_strands(&a.input)?;
    let s = if a.scale == 1.0 { s } else { s.map_points(|p| p * a.scale)? };
    write_strands(&a.output, &s)?;
    eprintln!("wrote {} strands, {} points to {}", s.num_strands(), s.num_points(), a.output.display());
    Ok(())
}

pub fn info(a: InfoArgs) -> CmdResult {
    let s = read_strands(&a.file)?;
    println!("file:     {}", a.file.display());
    println!("strands:  {}", s.num_strands());
    println!("points:   {}", s.num_points());
    if let (Some(st), Some((lo, hi))) = (s.length_stats(), s.bbox()) {
        let c = s.counts();
        let (cmin, cmax) = (c.iter().min().copied().unwrap_or(0), c.iter().max().copied().unwrap_or(0));
        println!(
            "points per strand: min {cmin}, max {cmax}, mean {:.1}",
            s.num_points() as f64 / s.num_strands() as f64
        );
        println!(
            "length:   min {:.4}, median {:.4}, mean {:.4}, max {:.4}, total {:.2}",
            st.min, st.median, st.mean, st.max, st.total
        );
        println!("bbox min: [{:.4}, {:.4}, {:.4}]", lo.x, lo.y, lo.z);
        println!("bbox max: [{:.4}, {:.4}, {:.4}]", hi.x, hi.y, hi.z);
        let size = hi - lo;
        println!("size:     [{:.4}, {:.4}, {:.4}]", size.x, size.y, size.z);
    }
    Ok(())
}
