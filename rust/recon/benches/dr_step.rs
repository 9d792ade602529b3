//! One DR step's objective (`hairrecon_recon::dr::optimize::Evaluator::evaluate`): four views
//! rendered, the loss images, the renderer's backward pass and the regularizers, for 20,000 strands
//! of 100 segments on a sphere of radius 0.09 m (2 million segments) in 256×384 px views, against
//! targets rendered from other strands. Two cases, as DR's two stages: the guide stage (2,000
//! guides, the children rendered through the child map and its backward pass) and the child stage
//! (every strand optimized). Throughput: segments × views.
//!
//! `cargo bench -p hairrecon-recon --bench dr_step` (add `-- --quick` for a short run).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::Vec3;
use hairrecon_core::Camera;
use hairrecon_raster::synthetic::sphere_strands;
use hairrecon_recon::dr::children::ChildMap;
use hairrecon_recon::dr::optimize::Evaluator;
use hairrecon_recon::dr::DrOptions;
use hairrecon_recon::grow::BlendParams;

mod dr_data;
use dr_data::{targets, WIDTH_M};

/// Eight views around the sphere, portrait 256×384 as the colours preset.
fn cameras() -> Vec<Camera> {
    (0..8)
        .map(|i| {
            let az = i as f32 * std::f32::consts::FRAC_PI_4;
            let eye = Vec3::new(az.cos(), az.sin(), 0.3) * 0.5;
            Camera::look_at(eye, Vec3::new(0.0, 0.0, -0.02), Vec3::Z, 0.8, 256, 384).expect("camera")
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let gt = sphere_strands(20_000, 100, 0.09, 0.25, 7);
    let strands = sphere_strands(20_000, 100, 0.09, 0.22, 8);
    let targets = targets(&gt, &cameras());
    let guides = strands.select(&(0..strands.num_strands()).step_by(10).collect::<Vec<_>>());
    let mut map = ChildMap::new(&guides, &strands, &BlendParams { k: 2, min_guide_fraction: 0.3, parting_reach: 0.5 });
    let opts = DrOptions { width_m: WIDTH_M, views_per_step: 4, ..Default::default() };
    let views = [0, 2, 5, 7];
    let segments = strands.num_points() - strands.num_strands();
    let mut g = c.benchmark_group(format!("DR step, {segments} segments x 4 views of 256x384"));
    g.sample_size(10);
    g.throughput(Throughput::Elements((segments * views.len()) as u64));
    let mut ev = Evaluator::new(guides.points(), guides.offsets(), Some(&map), &targets, &opts);
    let mut grad = vec![Vec3::ZERO; guides.num_points()];
    g.bench_function("guide stage (children through the child map)", |b| {
        b.iter(|| {
            ev.evaluate(guides.points(), guides.offsets(), Some(&mut map), &targets, &views, &opts, &mut grad)
                .expect("evaluate")
        })
    });
    let mut ev = Evaluator::new(strands.points(), strands.offsets(), None, &targets, &opts);
    let mut grad = vec![Vec3::ZERO; strands.num_points()];
    g.bench_function("child stage", |b| {
        b.iter(|| {
            ev.evaluate(strands.points(), strands.offsets(), None, &targets, &views, &opts, &mut grad)
                .expect("evaluate")
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
