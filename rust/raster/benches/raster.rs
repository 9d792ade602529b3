//! Forward + anti-aliasing + backward for 2.5 million segments (50,000 strands × 50 segments on a
//! sphere of radius 0.09 m) at 341×512 px (portrait, as the paper's 512 px high images), one view,
//! and the same segments drawn as anti-aliased hairlines by tiny-skia (forward only, the path built
//! and the points projected once, outside the timing), for a ratio measured in the same run.
//!
//! `cargo bench -p hairrecon-raster` (add `-- --quick` for a short run); or
//! `cargo run --release -p hairrecon-raster --example bench_quick` for a plain segments/second print.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::Vec3;
use hairrecon_core::Camera;
use hairrecon_raster::synthetic::sphere_strands;
use hairrecon_raster::{
    antialias_backward, antialias_forward, attributes_backward, rasterize, strand_segments, AaMethod, AaOutput,
    Buffers, Image, RasterSettings, Screen, SegmentGrads, SegmentShape, VertexGrads, Width,
};

fn setup() -> (Camera, Vec<Vec3>, Vec<[u32; 2]>) {
    let strands = sphere_strands(50_000, 50, 0.09, 0.25, 7);
    let cam = Camera::look_at(Vec3::new(0.0, -0.75, 0.02), Vec3::new(0.0, 0.0, -0.03), Vec3::Z, 0.55, 341, 512)
        .expect("camera");
    let segs = strand_segments(&strands);
    (cam, strands.points().to_vec(), segs)
}

fn bench(c: &mut Criterion) {
    let (cam, points, segs) = setup();
    let settings = RasterSettings { width: Width::World(0.0002), shape: SegmentShape::Quad, direction_3d: false };
    let mut g = c.benchmark_group("2.5M segments 341x512");
    g.sample_size(10);
    g.throughput(Throughput::Elements(segs.len() as u64));
    for method in AaMethod::ALL {
        let mut screen = Screen::default();
        let mut buf = Buffers::new();
        let mut aa = AaOutput::new(method);
        let mut d_attrs = Image::default();
        let mut sg = SegmentGrads::default();
        let mut vg = VertexGrads::default();
        let mut world = vec![Vec3::ZERO; points.len()];
        g.bench_function(format!("fwd+aa+bwd {}", method.name()), |b| {
            b.iter(|| {
                screen.set_projected(&cam, &points, &segs, settings).expect("project");
                rasterize(&screen, &mut buf);
                antialias_forward(&screen, &buf, &mut aa);
                // L = Σ coverage: ∂L/∂image = 1 in the coverage channel.
                let mut d = Image::zeros(aa.image.width, aa.image.height, aa.image.channels);
                d.data.iter_mut().step_by(aa.image.channels).for_each(|v| *v = 1.0);
                sg.reset(segs.len());
                antialias_backward(&screen, &buf, &aa, &d, &mut d_attrs, &mut sg).expect("backward");
                attributes_backward(&screen, &buf, &d_attrs, &mut sg);
                screen.backward_vertices(&sg, &mut vg);
                screen.backward_world(&cam, &points, &vg, &mut world);
            })
        });
    }
    {
        let mut screen = Screen::default();
        let mut buf = Buffers::new();
        g.bench_function("fwd rasterize only", |b| {
            b.iter(|| {
                screen.set_projected(&cam, &points, &segs, settings).expect("project");
                rasterize(&screen, &mut buf);
            })
        });
    }
    let path = tiny_skia_path(&cam, &points, &segs);
    let mut pm = tiny_skia::Pixmap::new(341, 512).expect("pixmap");
    let mut paint = tiny_skia::Paint::default();
    paint.set_color_rgba8(0, 0, 0, 255);
    paint.anti_alias = true;
    let stroke = tiny_skia::Stroke { width: 0.0, ..Default::default() };
    g.bench_function("tiny-skia AA hairlines (fwd only)", |b| {
        b.iter(|| {
            pm.fill(tiny_skia::Color::WHITE);
            pm.stroke_path(&path, &paint, &stroke, tiny_skia::Transform::identity(), None);
        })
    });
    g.finish();
}

/// All segments as one path of move-to/line-to pairs in pixels.
pub fn tiny_skia_path(cam: &Camera, points: &[Vec3], segs: &[[u32; 2]]) -> tiny_skia::Path {
    let mut pb = tiny_skia::PathBuilder::new();
    let mut last = u32::MAX;
    for s in segs {
        let (Some(a), Some(b)) = (cam.project(points[s[0] as usize]), cam.project(points[s[1] as usize])) else {
            continue;
        };
        if s[0] != last {
            pb.move_to(a.pixel.x + 0.5, a.pixel.y + 0.5);
        }
        pb.line_to(b.pixel.x + 0.5, b.pixel.y + 0.5);
        last = s[1];
    }
    pb.finish().expect("path")
}

criterion_group!(benches, bench);
criterion_main!(benches);
