//! Hard rasterization: coverage of pixel centres, depth order, bands, and the orientation attribute.

use glam::Vec2;
use hairrecon_raster::{channel, rasterize, Buffers, RasterSettings, Screen, SegmentShape, Width};

fn quad(width: f32) -> RasterSettings {
    RasterSettings { width: Width::Pixels(width), shape: SegmentShape::Quad, direction_3d: false }
}

#[test]
fn a_horizontal_quad_covers_exactly_its_pixel_centres() {
    // From x = 2.5 to 12.5 at y = 10.2, 1.2 px wide: covers y in [9.6, 10.8] -> row 10 only, x 3..=12.
    let s = Screen::from_pixels(20, 20, &[Vec2::new(2.5, 10.2), Vec2::new(12.5, 10.2)], None, &[[0, 1]], quad(1.2))
        .unwrap();
    let mut b = Buffers::new();
    rasterize(&s, &mut b);
    for y in 0..20 {
        for x in 0..20 {
            let want = y == 10 && (3..=12).contains(&x);
            assert_eq!(b.id(x, y) == 1, want, "pixel ({x}, {y})");
        }
    }
    assert_eq!(b.attrs.at(5, 10, channel::COVERAGE), 1.0);
    assert!((b.attrs.at(5, 10, channel::COS2) - 1.0).abs() < 1e-6);
}

#[test]
fn nearer_segment_wins_and_bands_join() {
    // Two crossing segments spanning several bands; the second is nearer.
    let pos = [Vec2::new(1.0, 1.0), Vec2::new(30.0, 30.0), Vec2::new(30.0, 1.0), Vec2::new(1.0, 30.0)];
    let depth = [2.0, 2.0, 1.0, 1.0];
    let s = Screen::from_pixels(32, 32, &pos, Some(&depth), &[[0, 1], [2, 3]], quad(2.0)).unwrap();
    let mut b = Buffers::new();
    rasterize(&s, &mut b);
    assert_eq!(b.id(15, 15), 2, "the nearer segment must win at the crossing");
    assert_eq!(b.id(5, 5), 1);
    assert_eq!(b.id(25, 25), 1);
    assert_eq!(b.id(5, 26), 2);
    // Diagonal: (cos 2θ, sin 2θ) = (0, 1) for 45°.
    assert!((b.attrs.at(5, 5, channel::SIN2) - 1.0).abs() < 1e-5);
}

#[test]
fn triangle_tapers_to_its_apex() {
    let s = Screen::from_pixels(
        40,
        10,
        &[Vec2::new(1.0, 5.0), Vec2::new(38.0, 5.0)],
        None,
        &[[0, 1]],
        RasterSettings { width: Width::Pixels(4.0), shape: SegmentShape::Triangle, direction_3d: false },
    )
    .unwrap();
    let mut b = Buffers::new();
    rasterize(&s, &mut b);
    // Half width 2 at x = 1 shrinking to 0 at x = 38: at x = 2 (half width 1.95) rows 4 to 6 are
    // covered and row 3 (2 px away) is not; at x = 30 (half width 0.43) only row 5 is.
    assert_eq!(b.id(2, 4), 1);
    assert_eq!(b.id(2, 3), 0);
    assert_eq!(b.id(30, 4), 0);
    assert_eq!(b.id(30, 5), 1);
}

#[test]
fn the_3d_direction_channels_hold_each_visible_segments_direction() {
    use glam::Vec3;
    use hairrecon_core::Camera;
    use hairrecon_raster::{AaMethod, Renderer};
    // Two 3D segments seen from +z: one along x (in front), one along y tilted in depth (behind it).
    let cam = Camera::look_at(Vec3::new(0.0, 0.0, 1.0), Vec3::ZERO, Vec3::Y, 0.8, 64, 64).unwrap();
    let pts =
        [Vec3::new(-0.2, 0.0, 0.1), Vec3::new(0.2, 0.0, 0.1), Vec3::new(0.1, -0.2, -0.1), Vec3::new(0.1, 0.2, 0.0)];
    let segs = [[0, 1], [2, 3]];
    let settings = RasterSettings { width: Width::Pixels(3.0), shape: SegmentShape::Quad, direction_3d: true };
    let s = Screen::project(&cam, &pts, &segs, settings).unwrap();
    let mut b = Buffers::new();
    rasterize(&s, &mut b);
    let mut r = Renderer::new(AaMethod::Ours);
    let aa = r.forward(&cam, &pts, &segs, settings).unwrap().clone();
    for (seg, at) in [(0usize, Vec3::new(-0.1, 0.0, 0.1)), (1, Vec3::new(0.1, 0.15, -0.0125))] {
        let px = cam.project(at).unwrap().pixel.round();
        let (x, y) = (px.x as u32, px.y as u32);
        assert_eq!(b.id(x, y), seg as u32 + 1, "pixel ({x}, {y})");
        let want = (pts[2 * seg + 1] - pts[2 * seg]).normalize();
        for k in 0..3 {
            assert!((b.attrs.at(x, y, channel::DIR3 + k) - want[k]).abs() < 1e-6, "segment {seg}, raster");
            assert!((aa.at(x, y, channel::DIR3 + k) - want[k]).abs() < 1e-6, "segment {seg}, anti-aliased");
        }
    }
    // where the nearer segment crosses the other, its direction wins
    let px = cam.project(Vec3::new(0.1, 0.0, 0.1)).unwrap().pixel.round();
    assert_eq!(b.id(px.x as u32, px.y as u32), 1);
    assert!((b.attrs.at(px.x as u32, px.y as u32, channel::DIR3) - 1.0).abs() < 1e-6);
}

/// The primitive stays small: the rasterizer streams millions of them per view (see [`Prim`]).
#[test]
fn a_primitive_is_44_bytes() {
    assert_eq!(std::mem::size_of::<hairrecon_raster::Prim>(), 44);
}
