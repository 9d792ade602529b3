//! Every calibration writer and its reader are inverses, in any world frame: a synthetic scene is
//! moved into a random similarity frame (`X' = s Q X + o`, cameras adjusted so that projections do
//! not change), written, read back, and every view must project every point within 1e-3 px of the
//! original camera, with and without lens distortion.

use std::path::{Path, PathBuf};

use hairrecon_import::colmap::{read_colmap, write_binary, write_text};
use hairrecon_import::metashape::{read_metashape, write_xml, write_xml_in_chunk};
use hairrecon_import::nerf::{read_nerf, write_transforms};
use hairrecon_import::pose::{self, Similarity};
use hairrecon_import::{Distortion, ImportError, Intrinsics, Scene, SceneView, Units};

/// SplitMix64: a tiny seeded generator, enough for test data.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [lo, hi).
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

pub fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("hairrecon-import-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn normalize(v: [f64; 3]) -> [f64; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / n, v[1] / n, v[2] / n]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// Six 640x480 cameras on a ring of radius 3 looking at the origin, and 200 points in a ball of
/// radius 0.6 around it (all in front of every camera).
fn synthetic_scene(rng: &mut Rng, fx: f64, fy: f64, distortion: Distortion, skew: f64) -> Scene {
    let mut views = Vec::new();
    for i in 0..6 {
        let a = i as f64 * std::f64::consts::TAU / 6.0 + rng.uniform(-0.2, 0.2);
        let c = [3.0 * a.cos(), 3.0 * a.sin(), rng.uniform(-0.8, 0.8)];
        let z = normalize([-c[0], -c[1], -c[2]]);
        let x = normalize(cross(z, [0.0, 0.0, 1.0]));
        let y = cross(z, x);
        let r = [x, y, z];
        let t = pose::translation(&r, &c);
        views.push(SceneView {
            name: format!("view_{i:03}.png"),
            image: PathBuf::from(format!("photos/sub/view_{i:03}.png")),
            width: 640,
            height: 480,
            intrinsics: Intrinsics {
                fx,
                fy,
                cx: 319.5 + rng.uniform(-5.0, 5.0),
                cy: 239.5 + rng.uniform(-5.0, 5.0),
                skew,
            },
            distortion,
            r,
            t,
        });
    }
    let points = (0..200)
        .map(|_| loop {
            let p = [rng.uniform(-0.6, 0.6), rng.uniform(-0.6, 0.6), rng.uniform(-0.6, 0.6)];
            if p.iter().map(|v| v * v).sum::<f64>() < 0.36 {
                break p;
            }
        })
        .collect();
    Scene { views, points, units: Units::Unknown, warnings: Vec::new() }
}

fn random_similarity(rng: &mut Rng) -> Similarity {
    let q = [rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0)];
    Similarity {
        rotation: pose::rotation_from_quaternion(q).unwrap(),
        translation: [rng.uniform(-100.0, 100.0), rng.uniform(-100.0, 100.0), rng.uniform(-100.0, 100.0)],
        scale: 10f64.powf(rng.uniform(-2.0, 2.0)),
    }
}

/// Every view of `read` (in the frame `s`) projects every point of `original` where `original`'s
/// views do, within 1e-3 px.
fn assert_same_projections(original: &Scene, read: &Scene, s: &Similarity, what: &str) {
    assert_eq!(original.views.len(), read.views.len(), "{what}: number of views");
    let mut worst = 0.0f64;
    for (a, b) in original.views.iter().zip(&read.views) {
        assert_eq!(a.name, b.name, "{what}: view name");
        assert_eq!(a.image, b.image, "{what}: image path");
        assert_eq!((a.width, a.height), (b.width, b.height), "{what}: image size");
        for p in &original.points {
            let pa = a.project(*p).expect("in front of the original camera");
            let pb = b.project(s.apply(p)).expect("in front of the read camera");
            worst = worst.max((pa[0] - pb[0]).abs()).max((pa[1] - pb[1]).abs());
        }
    }
    assert!(worst < 1e-3, "{what}: projections differ by up to {worst} px");
}

fn opencv_distortion() -> Distortion {
    Distortion { k: [-0.1, 0.02, 0.0, 0.0], d: [0.0; 3], p: [1e-3, 1e-3] }
}

type Writer = fn(&Path, &Scene) -> Result<(), ImportError>;
type Reader = fn(&Path) -> Result<Scene, ImportError>;

/// Writes and reads `scene` in 3 random frames with one format.
fn round_trip(scene: &Scene, rng: &mut Rng, file: &str, write: Writer, read: Reader, what: &str) {
    for k in 0..3 {
        let s = if k == 0 { Similarity::IDENTITY } else { random_similarity(rng) };
        let moved = scene.transformed(&s);
        let dir = tmpdir(&format!("{what}-{k}"));
        let path = if file.is_empty() { dir.clone() } else { dir.join(file) };
        write(&path, &moved).unwrap_or_else(|e| panic!("{what}: {e}"));
        let back = read(&path).unwrap_or_else(|e| panic!("{what}: {e}"));
        assert_same_projections(scene, &back, &s, what);
        assert!(back.warnings.is_empty(), "{what}: {:?}", back.warnings);
        if what.starts_with("colmap") {
            assert_eq!(back.points, moved.points, "{what}: points are exact");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

fn all_formats(scene: &Scene, rng: &mut Rng, tag: &str, colmap: bool, metashape: bool, nerf: bool) {
    if colmap {
        round_trip(scene, rng, "", write_text, read_colmap, &format!("colmap-text-{tag}"));
        round_trip(scene, rng, "", write_binary, read_colmap, &format!("colmap-binary-{tag}"));
    }
    if metashape {
        round_trip(scene, rng, "cameras.xml", write_xml, read_metashape, &format!("metashape-{tag}"));
    }
    if nerf {
        round_trip(scene, rng, "transforms.json", write_transforms, read_nerf, &format!("nerf-{tag}"));
    }
}

#[test]
fn pinhole_round_trips() {
    let mut rng = Rng(1);
    let simple = synthetic_scene(&mut rng, 600.0, 600.0, Distortion::default(), 0.0);
    all_formats(&simple, &mut rng, "simple-pinhole", true, true, true);
    let pinhole = synthetic_scene(&mut rng, 610.0, 595.0, Distortion::default(), 0.0);
    all_formats(&pinhole, &mut rng, "pinhole", true, true, true);
}

#[test]
fn distorted_round_trips() {
    let mut rng = Rng(2);
    let opencv = synthetic_scene(&mut rng, 610.0, 600.0, opencv_distortion(), 0.0);
    all_formats(&opencv, &mut rng, "opencv", true, true, true);
    // FULL_OPENCV: k3 and a rational denominator (COLMAP only).
    let mut d = opencv_distortion();
    d.k[2] = 0.003;
    d.d = [0.01, -0.002, 0.0005];
    let full = synthetic_scene(&mut rng, 610.0, 600.0, d, 0.0);
    all_formats(&full, &mut rng, "full-opencv", true, false, false);
    // k3 and k4 (Metashape, transforms.json), and skew (Metashape's b2).
    let mut d = opencv_distortion();
    d.k[2] = 0.003;
    d.k[3] = -0.0004;
    let k4 = synthetic_scene(&mut rng, 610.0, 600.0, d, 0.0);
    all_formats(&k4, &mut rng, "k4", false, true, true);
    let skewed = synthetic_scene(&mut rng, 610.0, 600.0, opencv_distortion(), 1.5);
    all_formats(&skewed, &mut rng, "skew", false, true, false);
}

/// A referenced Metashape chunk: cameras in an internal frame, the chunk transform (a similarity)
/// mapping it to the world frame.
#[test]
fn metashape_chunk_transform() {
    let mut rng = Rng(3);
    let scene = synthetic_scene(&mut rng, 610.0, 600.0, opencv_distortion(), 0.0);
    for k in 0..3 {
        let chunk = random_similarity(&mut rng);
        let dir = tmpdir(&format!("metashape-chunk-{k}"));
        let path = dir.join("cameras.xml");
        write_xml_in_chunk(&path, &scene, &chunk).unwrap();
        let back = read_metashape(&path).unwrap();
        assert_same_projections(&scene, &back, &Similarity::IDENTITY, "metashape chunk");
        for (a, b) in scene.views.iter().zip(&back.views) {
            let (ca, cb) = (pose::centre(&a.r, &a.t), pose::centre(&b.r, &b.t));
            assert!((0..3).all(|i| (ca[i] - cb[i]).abs() < 1e-9), "camera centres {ca:?} {cb:?}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

#[test]
fn writers_refuse_what_the_format_cannot_hold() {
    let mut rng = Rng(4);
    let dir = tmpdir("refuse");
    let skewed = synthetic_scene(&mut rng, 600.0, 600.0, Distortion::default(), 1.0);
    let e = write_text(&dir.join("colmap"), &skewed).unwrap_err();
    assert!(matches!(e, ImportError::Unwritable { .. }) && e.to_string().contains("skew"), "{e}");
    let e = write_transforms(&dir.join("t.json"), &skewed).unwrap_err();
    assert!(matches!(e, ImportError::Unwritable { .. }), "{e}");
    let mut d = opencv_distortion();
    d.d[0] = 0.1;
    let rational = synthetic_scene(&mut rng, 600.0, 600.0, d, 0.0);
    let e = write_xml(&dir.join("c.xml"), &rational).unwrap_err();
    assert!(matches!(e, ImportError::Unwritable { .. }) && e.to_string().contains("c.xml"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}
