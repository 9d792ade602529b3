//! Analytic gradients against central finite differences, on seeded random cases.
//!
//! Each case draws an image of 18–28 px, one to three segments (separate or chained into a strand,
//! quads or triangles, with depths so that they may occlude each other), a width of 0.3–3 px, and
//! the AA method `ours` or `nvdiffrast` (alternating). Splatting is not checked here: its gradient
//! is by construction not the derivative of its forward pass (Cole et al. 2021 hold the samples'
//! surface coordinates fixed, and the forward re-projects every sample onto its pixel centre), so
//! finite differences of its output are zero; `aa_splat`'s unit test checks it against differences
//! with frozen samples instead. Half of the cases are 2D (vertices are pixel positions), half are 3D
//! (vertices are world points seen by a random camera, width in pixels or in metres, so that the
//! gradient goes through the projection and the depth-dependent width). The loss is smooth in the
//! AA output: `L = Σ_p Σ_c w_pc ĉ_pc` with fixed random weights in [−1, 1] over all channels
//! (coverage and the orientation `(cos 2θ, sin 2θ)`).
//!
//! The hard raster is piecewise constant in the vertices, and the AA output is smooth only while the
//! ids and the chosen edges stay the same. So a coordinate is checked only if the perturbed renders
//! at `±h` have the same id buffer and the same saved edge choices as the unperturbed one; other
//! coordinates are skipped (and counted). Step: `h = 1e-2` px in 2D, in 3D the world step that moves
//! the projection by at most that much (`GRADCHECK_STEP` overrides it). Smaller steps drown in f32
//! rounding of the projection (at 1e-3 px, 3D cases fail on noise); larger ones skip more coordinates.
//!
//! Tolerance per coordinate: `|g − g_fd| ≤ 0.03 · max(|g|, |g_fd|) + 3e-3`; a case passes if all its
//! checked coordinates do. At least 98% of the cases with a checked coordinate must pass, and at least
//! 200 cases must have one.

use glam::{Vec2, Vec3};
use hairrecon_core::Camera;
use hairrecon_raster::{AaMethod, Image, RasterSettings, Renderer, SegmentShape, Width};

struct Rng(u64);
impl Rng {
    fn next_u32(&mut self) -> u32 {
        // PCG-XSH-RR.
        let old = self.0;
        self.0 = old.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        let x = (((old >> 18) ^ old) >> 27) as u32;
        x.rotate_right((old >> 59) as u32)
    }
    fn f(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 / (1u32 << 24) as f32
    }
    fn range(&mut self, a: f32, b: f32) -> f32 {
        a + (b - a) * self.f()
    }
    fn int(&mut self, n: u32) -> u32 {
        self.next_u32() % n
    }
}

#[derive(Debug, Clone)]
struct Case {
    method: AaMethod,
    w: u32,
    h: u32,
    pix: Vec<Vec2>,
    depth: Vec<f32>,
    segs: Vec<[u32; 2]>,
    settings: RasterSettings,
    camera: Option<Camera>,
    points: Vec<Vec3>,
}

fn make_case(rng: &mut Rng, i: usize) -> Case {
    let method = if i.is_multiple_of(2) { AaMethod::Ours } else { AaMethod::Nvdiffrast };
    let w = 18 + rng.int(11);
    let h = 18 + rng.int(11);
    let nseg = 1 + rng.int(3) as usize;
    let chained = rng.int(2) == 0;
    let mut pix = Vec::new();
    let mut segs = Vec::new();
    let pt = |rng: &mut Rng| Vec2::new(rng.range(2.0, w as f32 - 3.0), rng.range(2.0, h as f32 - 3.0));
    if chained {
        pix.push(pt(rng));
        for s in 0..nseg {
            let last = pix[s];
            let dir = Vec2::from_angle(rng.range(0.0, std::f32::consts::TAU));
            let p =
                (last + dir * rng.range(2.0, 9.0)).clamp(Vec2::splat(1.0), Vec2::new(w as f32 - 2.0, h as f32 - 2.0));
            pix.push(p);
            segs.push([s as u32, s as u32 + 1]);
        }
    } else {
        for s in 0..nseg {
            let a = pt(rng);
            let dir = Vec2::from_angle(rng.range(0.0, std::f32::consts::TAU));
            let b = (a + dir * rng.range(2.0, 12.0)).clamp(Vec2::splat(1.0), Vec2::new(w as f32 - 2.0, h as f32 - 2.0));
            pix.push(a);
            pix.push(b);
            segs.push([2 * s as u32, 2 * s as u32 + 1]);
        }
    }
    let depth: Vec<f32> = pix.iter().map(|_| rng.range(0.4, 0.6)).collect();
    let width_px = rng.range(0.3, 3.0);
    let shape = if rng.int(2) == 0 { SegmentShape::Quad } else { SegmentShape::Triangle };
    let three_d = (i / 2) % 2 == 1;
    let mut settings = RasterSettings { width: Width::Pixels(width_px), shape, direction_3d: false };
    let (camera, points) = if three_d {
        let eye = Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-0.5, 0.5)).normalize() * 0.5;
        let fov = rng.range(0.3, 0.7);
        let cam = Camera::look_at(eye, Vec3::ZERO, Vec3::Z, fov, w, h).expect("camera");
        let points: Vec<Vec3> = pix.iter().zip(&depth).map(|(p, &z)| cam.back_project(*p, z)).collect();
        if rng.int(2) == 0 {
            // Same pixel width at depth 0.5.
            let fy = cam.k().col(1).y;
            settings.width = Width::World(width_px * 0.5 / fy);
        }
        (Some(cam), points)
    } else {
        (None, Vec::new())
    };
    Case { method, w, h, pix, depth, segs, settings, camera, points }
}

/// Renders a case with its vertices replaced by `pix`/`points`; returns (image, ids, edges).
fn render(r: &mut Renderer, c: &Case, pix: &[Vec2], points: &[Vec3]) -> (Image, Vec<u32>, Vec<u32>) {
    match &c.camera {
        Some(cam) => {
            r.forward(cam, points, &c.segs, c.settings).expect("render");
        }
        None => {
            r.screen.set_pixels(c.w, c.h, pix, Some(&c.depth), &c.segs, c.settings).expect("screen");
            hairrecon_raster::rasterize(&r.screen, &mut r.buffers);
            hairrecon_raster::antialias_forward(&r.screen, &r.buffers, &mut r.aa);
        }
    }
    (r.aa.image.clone(), r.buffers.ids.clone(), r.aa.saved_edges().to_vec())
}

fn loss(img: &Image, wts: &[f32]) -> f64 {
    img.data.iter().zip(wts).map(|(&a, &b)| a as f64 * b as f64).sum()
}

#[test]
fn gradients_match_finite_differences() {
    let mut rng = Rng(0x5eed_0001);
    let ncases = 330;
    let (mut checked_cases, mut passed, mut coords_checked, mut coords_skipped) = (0, 0, 0, 0);
    let mut failures = Vec::new();
    for i in 0..ncases {
        let c = make_case(&mut rng, i);
        let mut r = Renderer::new(c.method);
        let (img, ids, edges) = render(&mut r, &c, &c.pix, &c.points);
        let wts: Vec<f32> = (0..img.data.len()).map(|_| rng.range(-1.0, 1.0)).collect();
        let d = Image { width: img.width, height: img.height, channels: img.channels, data: wts.clone() };
        // Analytic gradient.
        let analytic: Vec<f32> = match &c.camera {
            Some(cam) => {
                let mut g = vec![Vec3::ZERO; c.points.len()];
                r.backward(cam, &c.points, &d, &mut g).expect("backward");
                g.iter().flat_map(|v| v.to_array()).collect()
            }
            None => {
                let g = r.backward_screen(&d).expect("backward");
                g.pos.iter().flat_map(|v| v.to_array()).collect()
            }
        };
        let mut ok = true;
        let mut any = false;
        let mut worst = (0.0f32, 0.0f32, 0usize);
        for k in 0..analytic.len() {
            let (mut pp, mut pm) = (c.pix.clone(), c.pix.clone());
            let (mut xp, mut xm) = (c.points.clone(), c.points.clone());
            let h;
            if let Some(cam) = &c.camera {
                let j = cam.project_jacobian(c.points[k / 3]).expect("in front");
                let px_per_m = j[0][k % 3].hypot(j[1][k % 3]).max(1.0);
                h = step_px() / px_per_m;
                xp[k / 3][k % 3] += h;
                xm[k / 3][k % 3] -= h;
            } else {
                h = step_px();
                pp[k / 2][k % 2] += h;
                pm[k / 2][k % 2] -= h;
            }
            let (ip, idp, ep) = render(&mut r, &c, &pp, &xp);
            let (im, idm, em) = render(&mut r, &c, &pm, &xm);
            if idp != ids || idm != ids || ep != edges || em != edges {
                coords_skipped += 1;
                continue;
            }
            any = true;
            coords_checked += 1;
            let fd = ((loss(&ip, &wts) - loss(&im, &wts)) / (2.0 * h as f64)) as f32;
            let g = analytic[k];
            let err = (g - fd).abs();
            if err > 0.03 * g.abs().max(fd.abs()) + 3e-3 {
                ok = false;
                if err > worst.0 {
                    worst = (err, fd, k);
                }
            }
        }
        if any {
            checked_cases += 1;
            if ok {
                passed += 1;
            } else {
                failures.push(format!(
                    "case {i}: {:?} coord {} analytic {} fd {} ; {:?}",
                    c.method, worst.2, analytic[worst.2], worst.1, c
                ));
            }
        }
    }
    eprintln!(
        "gradcheck: {passed}/{checked_cases} cases pass ({coords_checked} coordinates checked, {coords_skipped} skipped)"
    );
    for f in failures.iter().take(5) {
        eprintln!("{f}");
    }
    assert!(checked_cases >= 200, "only {checked_cases} cases had a checkable coordinate");
    assert!(passed as f64 >= 0.98 * checked_cases as f64, "{passed}/{checked_cases} cases pass; first failures above");
}

fn step_px() -> f32 {
    std::env::var("GRADCHECK_STEP").ok().and_then(|s| s.parse().ok()).unwrap_or(1e-2)
}
