use hairrecon_raster::toy::{run_toy, ToyConfig};
use hairrecon_raster::AaMethod;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let m = AaMethod::parse(&args[1]).unwrap();
    let w: f32 = args[2].parse().unwrap();
    let it: usize = args[3].parse().unwrap();
    let t = std::time::Instant::now();
    let mut cfg = ToyConfig::paper(m, w, it);
    if args.len() > 4 && args[4] == "coverage" {
        cfg.target = hairrecon_raster::toy::ToyTarget::Coverage;
    }
    let r = run_toy(&cfg, |_| {}).unwrap();
    for s in r.curve.iter().step_by((it / 20).max(1)) {
        println!("{} loss {:.4} tip_err {:.2} ratio {:.3}", s.iter, s.loss, s.tip_error_px, s.length_ratio);
    }
    println!(
        "final loss {} err {} ratio {} tip {:?} in {:?}",
        r.final_loss,
        r.final_tip_error_px,
        r.final_length_ratio,
        r.final_tip,
        t.elapsed()
    );
}
