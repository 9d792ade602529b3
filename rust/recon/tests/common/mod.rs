//! A synthetic capture for the pipeline tests: a spherical head with a layer of hair strands that
//! flow from the crown downward with a swirl, seen by 16 cameras; images are drawn strand by strand
//! (anti-aliased lines, painter's order, the head occluding what lies behind it), with ground-truth
//! strands, orientation maps and hair masks. Everything is seeded and deterministic.

#![allow(dead_code)]

use std::f32::consts::PI;
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};
use hairrecon_core::capture::{CaptureSpec, ViewSpec};
use hairrecon_core::formats::{write_mesh, write_strands};
use hairrecon_core::{Camera, StrandSet, TriMesh};
use hairrecon_recon::orient2d::OrientationMap;

/// A scratch folder under the system's temporary directory, `hairrecon-NAME-PID`, made empty; removed
/// when the test that holds it passes, kept (and named on stderr) when it fails, to look at.
#[derive(Debug)]
pub struct Scratch(PathBuf);

impl Scratch {
    pub fn new(name: &str) -> Self {
        let d = std::env::temp_dir().join(format!("hairrecon-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        Self(d)
    }
}

impl std::ops::Deref for Scratch {
    type Target = PathBuf;
    fn deref(&self) -> &PathBuf {
        &self.0
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("the failed test's files are kept in {}", self.0.display());
        } else {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

pub const HEAD_R: f32 = 0.09;
/// The raw mesh: the outer hair surface over the hair, the head below it.
pub const RAW_OVER_HAIR: f32 = 0.0085;
pub const SCALP_MAX_POLAR_DEG: f32 = 80.0;

pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// A UV sphere of radius `r`, polar angle limited to `max_polar` (radians; π for a full sphere).
pub fn sphere(r: f32, max_polar: f32, rings: usize, segs: usize) -> TriMesh {
    let mut v = vec![Vec3::new(0.0, 0.0, r)];
    for i in 1..=rings {
        let th = max_polar * i as f32 / rings as f32;
        for j in 0..segs {
            let ph = 2.0 * PI * j as f32 / segs as f32;
            v.push(r * Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()));
        }
    }
    let full = (max_polar - PI).abs() < 1e-4;
    if full {
        // The last ring collapsed to the south pole: replace it by one vertex.
        v.truncate(1 + (rings - 1) * segs);
        v.push(Vec3::new(0.0, 0.0, -r));
    }
    let mut t = Vec::new();
    let ring = |i: usize, j: usize| (1 + (i - 1) * segs + j % segs) as u32;
    for j in 0..segs {
        t.push([0, ring(1, j), ring(1, j + 1)]);
    }
    let last = if full { rings - 1 } else { rings };
    for i in 1..last {
        for j in 0..segs {
            let (a, b, c, d) = (ring(i, j), ring(i, j + 1), ring(i + 1, j), ring(i + 1, j + 1));
            t.push([a, c, d]);
            t.push([a, d, b]);
        }
    }
    if full {
        let s = (v.len() - 1) as u32;
        for j in 0..segs {
            t.push([ring(rings - 1, j), s, ring(rings - 1, j + 1)]);
        }
    }
    TriMesh::new(v, t, None, None).unwrap()
}

/// The raw mesh: a sphere RAW_OVER_HAIR above the head down to 112° of polar angle, falling onto
/// the head (+0.5 mm) by 125°.
pub fn raw_mesh() -> TriMesh {
    let mut m = sphere(1.0, PI, 72, 96);
    for v in &mut m.vertices {
        let th = v.z.clamp(-1.0, 1.0).acos().to_degrees();
        let f = ((th - 112.0) / 13.0).clamp(0.0, 1.0);
        let r = HEAD_R + RAW_OVER_HAIR * (1.0 - f) + 0.0005 * f;
        *v *= r;
    }
    m
}

/// Ground-truth strands: roots on the scalp cap, rising to a layer of the hair volume, then
/// flowing down and around.
pub fn make_strands(n: usize, seed: u64) -> StrandSet {
    let mut rng = Rng::new(seed);
    let mut points = Vec::new();
    let mut counts = Vec::new();
    let max_polar = (SCALP_MAX_POLAR_DEG - 5.0).to_radians();
    for _ in 0..n {
        // Area-uniform on the cap.
        let cmin = max_polar.cos();
        let th0 = (1.0 - rng.f32() * (1.0 - cmin)).acos();
        let ph0 = 2.0 * PI * rng.f32();
        let h = 0.002 + 0.006 * rng.f32();
        let th_end = (100.0 + 15.0 * rng.f32()).to_radians();
        let swirl = 0.35;
        let step = 0.002;
        let mut s = 0.0f32;
        let mut th = th0;
        let mut pts = Vec::new();
        loop {
            let rise = (s / 0.006).min(1.0);
            let r = HEAD_R + h * rise;
            let ph = ph0 + swirl * (th - th0);
            pts.push(r * Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()));
            if th >= th_end || pts.len() > 400 {
                break;
            }
            s += step;
            if s > 0.004 {
                // Advance along the sphere by about `step` of arc.
                let dth = step / (r * (1.0 + swirl * swirl * th.sin().powi(2)).sqrt());
                th += dth;
            }
        }
        counts.push(pts.len() as u32);
        points.extend(pts);
    }
    StrandSet::new(points, counts).unwrap()
}

/// 16 cameras around the head: 10 at 15° elevation, 6 at 55°.
pub fn cameras(size: u32) -> Vec<Camera> {
    let mut cams = Vec::new();
    for (count, elev) in [(10usize, 15f32), (6, 55.0)] {
        for k in 0..count {
            let az = 2.0 * PI * k as f32 / count as f32 + if count == 6 { 0.3 } else { 0.0 };
            let e = elev.to_radians();
            let eye = 0.6 * Vec3::new(e.cos() * az.cos(), e.cos() * az.sin(), e.sin());
            cams.push(Camera::look_at(eye, Vec3::ZERO, Vec3::Z, 30f32.to_radians(), size, size).unwrap());
        }
    }
    cams
}

/// Whether the head sphere hides `p` from the camera centre `c`.
fn behind_head(c: Vec3, p: Vec3) -> bool {
    let d = p - c;
    let len = d.length();
    let u = d / len;
    let b = c.dot(u);
    let disc = b * b - (c.length_squared() - HEAD_R * HEAD_R);
    if disc <= 0.0 {
        return false;
    }
    let t0 = -b - disc.sqrt();
    t0 > 0.0 && t0 < len - 1e-4
}

pub struct Rendered {
    pub image: Vec<f32>,
    pub mask: Vec<bool>,
    /// The strands' own alpha (the largest per pixel), not dilated.
    pub coverage: Vec<f32>,
    pub gt: OrientationMap,
}

/// Draws the strands into one view.
pub fn render(cam: &Camera, strands: &StrandSet) -> Rendered {
    let (w, h) = (cam.width() as usize, cam.height() as usize);
    let c = cam.center();
    // Background, then the head sphere shaded by its normal's facing ratio.
    let mut img = vec![0.05f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let d = cam.ray_direction(Vec2::new(x as f32, y as f32));
            let b = c.dot(d);
            let disc = b * b - (c.length_squared() - HEAD_R * HEAD_R);
            if disc > 0.0 {
                let p = c + d * (-b - disc.sqrt());
                img[y * w + x] = 0.25 + 0.15 * (-d.dot(p.normalize()));
            }
        }
    }
    // Segments, far to near.
    let mut segs: Vec<(f32, Vec3, Vec3, f32)> = Vec::new();
    for (si, s) in strands.iter().enumerate() {
        let shade = 0.7 + 0.25 * (((si * 7919) % 101) as f32 / 100.0);
        for wdw in s.windows(2) {
            let depth = cam.to_camera(0.5 * (wdw[0] + wdw[1])).z;
            segs.push((depth, wdw[0], wdw[1], shade));
        }
    }
    segs.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut theta = vec![0.0f32; w * h];
    let mut weight = vec![0.0f32; w * h];
    let mut cover = vec![0.0f32; w * h];
    for &(_, a, b, shade) in &segs {
        let (Some(pa), Some(pb)) = (cam.project(a), cam.project(b)) else { continue };
        let dir = pb.pixel - pa.pixel;
        let len = dir.length();
        if len < 1e-6 {
            continue;
        }
        let mut ang = dir.y.atan2(dir.x);
        if ang < 0.0 {
            ang += PI;
        }
        if ang >= PI {
            ang -= PI;
        }
        let n = (len / 0.5).ceil() as usize;
        for k in 0..=n {
            let f = k as f32 / n as f32;
            let p3 = a + (b - a) * f;
            if behind_head(c, p3) {
                continue;
            }
            let q = pa.pixel + dir * f;
            let (x0, y0) = (q.x.round() as i64, q.y.round() as i64);
            for yy in y0 - 1..=y0 + 1 {
                for xx in x0 - 1..=x0 + 1 {
                    if xx < 0 || yy < 0 || xx >= w as i64 || yy >= h as i64 {
                        continue;
                    }
                    // Distance to the segment's line.
                    let rel = Vec2::new(xx as f32, yy as f32) - pa.pixel;
                    let perp = (rel.x * dir.y - rel.y * dir.x).abs() / len;
                    let along = (Vec2::new(xx as f32, yy as f32) - q).length();
                    if along > 1.0 {
                        continue;
                    }
                    let alpha = (-perp * perp / (2.0 * 0.35 * 0.35)).exp() * 0.5;
                    let i = yy as usize * w + xx as usize;
                    img[i] = img[i] * (1.0 - alpha) + shade * alpha;
                    cover[i] = cover[i].max(alpha);
                    if alpha > 0.25 {
                        theta[i] = ang;
                        weight[i] = 1.0;
                    }
                }
            }
        }
    }
    // Mask: covered pixels dilated by 2.
    let mut mask = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            if cover[y * w + x] > 0.2 {
                for yy in y.saturating_sub(2)..(y + 3).min(h) {
                    for xx in x.saturating_sub(2)..(x + 3).min(w) {
                        mask[yy * w + xx] = true;
                    }
                }
            }
        }
    }
    let gt = OrientationMap { width: w as u32, height: h as u32, theta, confidence: weight };
    Rendered { image: img, mask, coverage: cover, gt }
}

/// Writes a complete capture folder and returns its path.
pub fn write_capture(dir: &Path, n_strands: usize, size: u32, seed: u64) -> PathBuf {
    write_capture_with(dir, n_strands, size, seed, false)
}

/// [`write_capture`]; with `coverage_masks`, each mask is the strands' alpha (twice the painted
/// alpha, at most 1; not dilated) instead of the dilated binary mask: a matte as a renderer's
/// alpha gives it, which the DR silhouette loss compares with rendered coverage.
pub fn write_capture_with(dir: &Path, n_strands: usize, size: u32, seed: u64, coverage_masks: bool) -> PathBuf {
    let _ = std::fs::remove_dir_all(dir);
    for sub in ["images", "masks", "gt/orientation"] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
    }
    let strands = make_strands(n_strands, seed);
    write_strands(dir.join("gt/strands.hair"), &strands).unwrap();
    write_mesh(dir.join("raw_mesh.ply"), &raw_mesh()).unwrap();
    write_mesh(dir.join("head.ply"), &sphere(HEAD_R, PI, 48, 96)).unwrap();
    write_mesh(dir.join("scalp.ply"), &sphere(HEAD_R, SCALP_MAX_POLAR_DEG.to_radians(), 24, 96)).unwrap();
    let mut views = Vec::new();
    for (i, cam) in cameras(size).iter().enumerate() {
        let name = format!("view_{i:03}");
        let r = render(cam, &strands);
        let img = image::GrayImage::from_fn(size, size, |x, y| {
            image::Luma([(r.image[(y * size + x) as usize].clamp(0.0, 1.0) * 255.0) as u8])
        });
        img.save(dir.join(format!("images/{name}.png"))).unwrap();
        let m = image::GrayImage::from_fn(size, size, |x, y| {
            let i = (y * size + x) as usize;
            let v = if coverage_masks { (2.0 * r.coverage[i]).min(1.0) } else { f32::from(u8::from(r.mask[i])) };
            image::Luma([(v * 255.0).round() as u8])
        });
        m.save(dir.join(format!("masks/{name}.png"))).unwrap();
        r.gt.save_exr(&dir.join(format!("gt/orientation/{name}.exr"))).unwrap();
        views.push(ViewSpec {
            name: name.clone(),
            image: format!("images/{name}.png").into(),
            mask: Some(format!("masks/{name}.png").into()),
            width: size,
            height: size,
            k: cam.k_rows(),
            r: cam.r_rows(),
            t: cam.t().to_array(),
            gt_orientation: Some(format!("gt/orientation/{name}.exr").into()),
            gt_depth: None,
            original: None,
        });
    }
    let spec = CaptureSpec {
        version: 1,
        units: "metres".into(),
        frame: None,
        convention: "opencv".into(),
        views,
        raw_mesh: "raw_mesh.ply".into(),
        head_mesh: Some("head.ply".into()),
        scalp_mesh: Some("scalp.ply".into()),
        gt_strands: Some("gt/strands.hair".into()),
        to_canonical: None,
    };
    std::fs::write(dir.join("capture.json"), serde_json::to_string_pretty(&spec).unwrap()).unwrap();
    dir.to_path_buf()
}
