//! Prints the time of one metric evaluation on the benchmark's data (50,000 strands × 100 points per
//! side), for a quick figure without criterion's repetitions:
//! `cargo run --release -p hairrecon-core --example metric_timing` (`JITTER=0.02` for a poor prediction).

#[path = "../benches/metric_data.rs"]
mod metric_data;

fn main() {
    let gt = metric_data::head_like(50_000, 100, 1, 0.0);
    let jitter = std::env::var("JITTER").ok().and_then(|v| v.parse().ok()).unwrap_or(0.003);
    let pred = metric_data::head_like(50_000, 100, 2, jitter);
    let t = std::time::Instant::now();
    let r = hairrecon_core::metric::evaluate(&pred, &gt, &Default::default()).expect("metric");
    println!("threads: {}, time: {:.2} s", rayon::current_num_threads(), t.elapsed().as_secs_f64());
    print!("{}", r.table());
}
