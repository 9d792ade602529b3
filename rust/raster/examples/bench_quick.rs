//! Prints segments/second of forward + AA + backward for 2.5M segments at 341×512 px, and of
//! tiny-skia's anti-aliased hairlines for the same segments (forward only): the median of 5 runs after
//! a warm-up. `cargo run --release -p hairrecon-raster --example bench_quick`.

use std::time::Instant;

use glam::Vec3;
use hairrecon_core::Camera;
use hairrecon_raster::synthetic::sphere_strands;
use hairrecon_raster::{strand_segments, AaMethod, Image, RasterSettings, Renderer, SegmentShape, Width};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn time(mut f: impl FnMut()) -> f64 {
    f();
    median(
        (0..5)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64()
            })
            .collect(),
    )
}

fn main() {
    let strands = sphere_strands(50_000, 50, 0.09, 0.25, 7);
    let cam = Camera::look_at(Vec3::new(0.0, -0.75, 0.02), Vec3::new(0.0, 0.0, -0.03), Vec3::Z, 0.55, 341, 512)
        .expect("camera");
    let points = strands.points().to_vec();
    let segs = strand_segments(&strands);
    let n = segs.len() as f64;
    let settings = RasterSettings { width: Width::World(0.0002), shape: SegmentShape::Quad, direction_3d: false };
    println!("{} segments, 341x512 px, {} rayon threads", segs.len(), rayon::current_num_threads());
    for method in AaMethod::ALL {
        let mut r = Renderer::new(method);
        let mut grad = vec![Vec3::ZERO; points.len()];
        let mut covered = 0;
        let t_fwd = time(|| {
            let img = r.forward(&cam, &points, &segs, settings).expect("render");
            covered = img.data.iter().step_by(img.channels).filter(|&&v| v > 0.0).count();
        });
        let t = time(|| {
            let img = r.forward(&cam, &points, &segs, settings).expect("render");
            let mut d = Image::zeros(img.width, img.height, img.channels);
            d.data.iter_mut().step_by(img.channels).for_each(|v| *v = 1.0);
            r.backward(&cam, &points, &d, &mut grad).expect("backward");
        });
        println!(
            "{:<10} fwd+aa: {:7.1} ms ({:6.1} M seg/s); fwd+aa+bwd: {:7.1} ms ({:6.1} M seg/s); {} px > 0",
            method.name(),
            t_fwd * 1e3,
            n / t_fwd / 1e6,
            t * 1e3,
            n / t / 1e6,
            covered
        );
    }
    let mut pb = tiny_skia::PathBuilder::new();
    let mut last = u32::MAX;
    for s in &segs {
        let (Some(a), Some(b)) = (cam.project(points[s[0] as usize]), cam.project(points[s[1] as usize])) else {
            continue;
        };
        if s[0] != last {
            pb.move_to(a.pixel.x + 0.5, a.pixel.y + 0.5);
        }
        pb.line_to(b.pixel.x + 0.5, b.pixel.y + 0.5);
        last = s[1];
    }
    let path = pb.finish().expect("path");
    let mut pm = tiny_skia::Pixmap::new(341, 512).expect("pixmap");
    let mut paint = tiny_skia::Paint::default();
    paint.set_color_rgba8(0, 0, 0, 255);
    paint.anti_alias = true;
    let stroke = tiny_skia::Stroke { width: 0.0, ..Default::default() };
    let t = time(|| {
        pm.fill(tiny_skia::Color::WHITE);
        pm.stroke_path(&path, &paint, &stroke, tiny_skia::Transform::identity(), None);
    });
    println!("tiny-skia  AA hairlines fwd: {:7.1} ms ({:6.1} M seg/s), one thread", t * 1e3, n / t / 1e6);
}
