//! Benchmark of the strand metric: 50,000 strands × 100 points on each side (issue 2).
//!
//! Ground truth: strands rooted on a sphere of radius 9 cm, 100 points each, 20 cm long (2 mm
//! segments) falling down and outward with a gentle wave. Prediction: the same strands displaced by
//! a per-strand offset of up to 1.5 mm and a small bend, so that all match branches are exercised.
//! Run: `cargo bench -p hairrecon-core --bench metric`.

use criterion::{criterion_group, criterion_main, Criterion};
use hairrecon_core::metric::{evaluate, MetricOptions};

mod metric_data;
use metric_data::head_like;

fn bench_metric(c: &mut Criterion) {
    let gt = head_like(50_000, 100, 1, 0.0);
    let pred = head_like(50_000, 100, 2, 0.003);
    let mut g = c.benchmark_group("metric");
    g.sample_size(10);
    g.bench_function("eval_50k_strands_x100_points", |b| {
        b.iter(|| evaluate(&pred, &gt, &MetricOptions::default()).expect("metric"))
    });
    g.finish();
    let r = evaluate(&pred, &gt, &MetricOptions::default()).expect("metric");
    eprint!("{}", r.table());
}

criterion_group!(benches, bench_metric);
criterion_main!(benches);
