//! Measurements on a rendered capture (not run by default: `HAIRRECON_CAPTURE=DIR cargo test -p
//! hairrecon-recon --test real_capture -- --ignored --nocapture`). They print numbers for tuning;
//! the floors live in `pipeline_synthetic.rs`.

use hairrecon_core::capture::Capture;
use hairrecon_recon::orient2d::{
    load_mask, orientation_errors, summarize_errors, GaborBank, GaborParams, GrayImage, OrientationMap,
};

fn capture() -> Option<Capture> {
    let dir = std::env::var("HAIRRECON_CAPTURE").ok()?;
    Some(Capture::load(dir).unwrap())
}

#[test]
#[ignore]
fn orient2d_parameter_sweep() {
    let Some(cap) = capture() else { return };
    let views: Vec<_> = cap.views.iter().step_by(2).collect();
    let data: Vec<(GrayImage, GrayImage, OrientationMap)> = views
        .iter()
        .map(|v| {
            let img = GrayImage::load(&v.image).unwrap();
            let mask = GrayImage::load(v.mask.as_ref().unwrap()).unwrap();
            let gt = OrientationMap::load_exr(v.gt_orientation.as_ref().unwrap()).unwrap();
            (img, mask, gt)
        })
        .collect();
    let _ = load_mask;
    for &(n, sigma, lambda, gamma) in
        &[(32usize, 2.0f32, 3.0f32, 0.5f32), (32, 3.0, 6.0, 0.5), (24, 3.0, 6.0, 0.5), (24, 4.0, 8.0, 0.5)]
    {
        let bank = GaborBank::new(GaborParams { orientations: n, sigma, lambda, gamma, ..Default::default() });
        for thr in [0.1f32, 0.5] {
            let mut errs = Vec::new();
            for (img, mask, gt) in &data {
                let m: Vec<bool> = mask.data.iter().map(|&v| v >= thr).collect();
                let map = bank.compute(img, Some(&m));
                errs.extend(orientation_errors(&map, gt));
            }
            let s = summarize_errors(errs);
            println!(
                "n {n} sigma {sigma} lambda {lambda} gamma {gamma} mask>={thr}: mean {:.1}°, confident half {:.1}°, {} px",
                s.mean_deg, s.mean_confident_half_deg, s.pixels
            );
        }
    }
}

#[test]
#[ignore]
fn orient3d_parameter_sweep() {
    use hairrecon_core::formats::{read_mesh, read_strands};
    use hairrecon_core::Bvh;
    use hairrecon_recon::metrics::{score_points, PointIndex};
    use hairrecon_recon::pipeline::{orient2d_stage, ReconstructOptions};
    use hairrecon_recon::points3d::{estimate, LineMvsParams, MvsView};
    use hairrecon_recon::progress::NoProgress;
    let Some(cap) = capture() else { return };
    let out = std::env::temp_dir().join(format!("hairrecon-sweep3d-{}", std::process::id()));
    let opts = ReconstructOptions { write_pictures: false, ..Default::default() };
    let (maps, _) = orient2d_stage(&cap, &out, &opts, &NoProgress).unwrap();
    let images: Vec<GrayImage> = cap.views.iter().map(|v| GrayImage::load(&v.image).unwrap()).collect();
    let views = MvsView::for_capture(&cap, &maps, &images);
    let raw = Bvh::new(read_mesh(&cap.raw_mesh).unwrap());
    let gt = read_strands(cap.gt_strands.as_ref().unwrap()).unwrap();
    let gi = PointIndex::from_strands(&gt, 0.001);
    let surface: Vec<usize> =
        (0..gi.len()).filter(|&i| raw.signed_distance(gi.points[i], 0.02).is_some_and(|d| d > -0.003)).collect();
    let base = LineMvsParams::default();
    let variants: Vec<(&str, LineMvsParams)> = vec![
        ("default", base.clone()),
        ("stride 1", LineMvsParams { stride: 1, ..base.clone() }),
        ("max_cost 0.12", LineMvsParams { max_cost: 0.12, ..base.clone() }),
        ("agree 20", LineMvsParams { agree_angle_deg: 20.0, ..base.clone() }),
        ("min_agree 1", LineMvsParams { min_agree: 1, ..base.clone() }),
        (
            "cost .12 agree 20 stride 1",
            LineMvsParams { max_cost: 0.12, agree_angle_deg: 20.0, stride: 1, ..base.clone() },
        ),
        ("no photometric", base.clone()),
    ];
    for (name, p) in variants {
        let vs: Vec<MvsView> = if name == "no photometric" {
            views.iter().map(|v| MvsView { image: None, ..*v }).collect()
        } else {
            views.clone()
        };
        let pts = estimate(&vs, &raw, &p, &NoProgress).unwrap();
        let s = score_points(&pts.positions, &pts.directions, &gi, &surface, 0.002, 20f32.to_radians());
        println!(
            "{name}: {} points, precision {:.1}, coverage {:.1} of {}",
            s.points, s.precision, s.coverage, s.surface_points
        );
    }
    let _ = std::fs::remove_dir_all(&out);
}

/// The whole pipeline; the output folder is `HAIRRECON_OUT` (default: a temporary folder).
#[test]
#[ignore]
fn full_pipeline() {
    use hairrecon_recon::pipeline::{reconstruct, ReconstructOptions};
    use hairrecon_recon::progress::NoProgress;
    let Some(cap) = capture() else { return };
    let out = std::env::var("HAIRRECON_OUT")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|_| std::env::temp_dir().join(format!("hairrecon-full-{}", std::process::id())));
    let r = reconstruct(&cap, &out, &ReconstructOptions::default(), &NoProgress).unwrap();
    println!("{:?}", r.stage_times);
    for (k, v) in r.metrics.as_object().unwrap() {
        if k.starts_with("init") {
            let s = &v["undirected"][1];
            println!("{k}: undirected 2 mm/20°: P {:.1} R {:.1} F1 {:.1}", s["precision"], s["recall"], s["f1"]);
        } else {
            println!("{k}: {v}");
        }
    }
}
