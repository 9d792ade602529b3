//! The reparameterization's system `M = (I + λL)_ff` (see `hairrecon_recon::dr::reparam`) for
//! 20,000 strands of 101 points on a sphere of radius 0.09 m (2 million free points, DR's default
//! λ = 10, N tying each strand to its 10 nearest at half its length with weight 0.05): building it,
//! one product `M x`, and solves of `M x = b` to DR's tolerance of 1e-3, from zero and warm-started
//! from the solution of a nearby right-hand side (as DR's second and later steps are).
//!
//! `cargo bench -p hairrecon-recon --bench reparam` (add `-- --quick` for a short run).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::Vec3;
use hairrecon_raster::synthetic::sphere_strands;
use hairrecon_recon::dr::reparam::{KnnKey, LaplacianParams, Reparam};

fn bench(c: &mut Criterion) {
    let strands = sphere_strands(20_000, 100, 0.09, 0.25, 7);
    let (x, offsets) = (strands.points(), strands.offsets());
    let params = LaplacianParams { lambda: 10.0, k_neighbors: 10, neighbor_weight: 0.05, key: KnnKey::Middle };
    let mut m = Reparam::new(x, offsets, &params);
    m.tolerance = 1e-3;
    let n = m.len();
    let b: Vec<Vec3> = (0..n).map(|i| Vec3::new((i as f32 * 0.37).sin(), (i as f32 * 0.11).cos(), 0.5)).collect();
    let b2: Vec<Vec3> = b.iter().enumerate().map(|(i, v)| *v * (1.0 + 0.05 * (i as f32 * 0.01).sin())).collect();
    let mut g = c.benchmark_group(format!("reparam {n} free points"));
    g.sample_size(10);
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("build", |bch| bch.iter(|| Reparam::new(x, offsets, &params)));
    let mut out = vec![Vec3::ZERO; n];
    g.bench_function("apply", |bch| bch.iter(|| m.apply(&b, &mut out)));
    g.bench_function("solve from zero", |bch| {
        bch.iter(|| {
            out.iter_mut().for_each(|v| *v = Vec3::ZERO);
            m.solve(&b, &mut out);
        })
    });
    let mut warm = vec![Vec3::ZERO; n];
    m.solve(&b, &mut warm);
    g.bench_function("solve warm", |bch| {
        bch.iter(|| {
            out.copy_from_slice(&warm);
            m.solve(&b2, &mut out);
        })
    });
    g.finish();
    out.iter_mut().for_each(|v| *v = Vec3::ZERO);
    m.solve(&b, &mut out);
    let cold = m.last_iterations;
    out.copy_from_slice(&warm);
    m.solve(&b2, &mut out);
    println!("CG iterations: {cold} from zero, {} warm", m.last_iterations);
}

criterion_group!(benches, bench);
criterion_main!(benches);
