//! Stage timings of the metric on 10,000 strands (for profiling):
//! `cargo run --release -p hairrecon-core --example metric_profile`.

#[path = "../benches/metric_data.rs"]
mod metric_data;
use hairrecon_core::metric::{OrientedPoints, PAPER_THRESHOLDS};
use std::time::Instant;

fn main() {
    let gt =
        metric_data::head_like(std::env::var("N").ok().and_then(|v| v.parse().ok()).unwrap_or(10_000), 100, 1, 0.0);
    let pred =
        metric_data::head_like(std::env::var("N").ok().and_then(|v| v.parse().ok()).unwrap_or(10_000), 100, 2, 0.003);
    let t = Instant::now();
    let a = OrientedPoints::from_strands(&pred, 0.001).unwrap();
    let b = OrientedPoints::from_strands(&gt, 0.001).unwrap();
    println!("resample + trees: {:.2} s ({} and {} points)", t.elapsed().as_secs_f64(), a.len(), b.len());
    let t = Instant::now();
    let r = b.match_counts(&a, &PAPER_THRESHOLDS);
    println!("precision queries: {:.2} s {:?}", t.elapsed().as_secs_f64(), r);
}
