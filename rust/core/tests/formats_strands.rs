//! Strand formats through files: the round trip .hair -> .data -> .ply -> .obj -> .hair, extension
//! dispatch, and the `.hair` per-point arrays.

use std::path::PathBuf;

use glam::Vec3;
use hairrecon_core::formats::{
    read_hair, read_strands, read_strands_with, write_hair, write_strands, FormatErrorKind, HairFile, StrandReadOptions,
};
use hairrecon_core::StrandSet;

/// A seeded xorshift generator.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn f32(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn tmp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("hairrecon-strands-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Random strands: random walks of 2..=80 points, coordinates of widely varying magnitude.
fn random_strands(seed: u64, n: usize) -> StrandSet {
    let mut rng = Rng(seed);
    let mut points = Vec::new();
    let mut counts = Vec::new();
    for _ in 0..n {
        let k = 2 + (rng.next() % 79) as u32;
        let scale = [1e-4f32, 0.01, 0.3, 7.0, 1e5][(rng.next() % 5) as usize];
        let mut p = Vec3::new(rng.f32() - 0.5, rng.f32() - 0.5, rng.f32() - 0.5) * scale;
        for _ in 0..k {
            points.push(p);
            p += Vec3::new(rng.f32() - 0.5, rng.f32() - 0.5, rng.f32()) * scale * 0.05;
        }
        counts.push(k);
    }
    StrandSet::new(points, counts).unwrap()
}

#[test]
fn round_trip_through_every_strand_format_keeps_every_point() {
    let d = tmp_dir("chain");
    let original = random_strands(2024, 300);
    let mut current = original.clone();
    for name in ["a.hair", "b.data", "c.ply", "d.obj", "e.hair"] {
        let p = d.join(name);
        write_strands(&p, &current).unwrap();
        current = read_strands(&p).unwrap();
        assert_eq!(current.counts(), original.counts(), "{name}");
        let mut worst = 0.0f32;
        for (a, b) in original.points().iter().zip(current.points()) {
            worst = worst.max((*a - *b).length() / a.length().max(1e-30));
        }
        assert!(worst <= 1e-6, "{name}: relative error {worst}");
    }
    // Every format stores f32 exactly (OBJ prints shortest round-trip decimals): the chain is lossless.
    assert_eq!(current, original);
    // Files are exactly the expected sizes: no padding, nothing left over.
    let (s, n) = (original.num_strands() as u64, original.num_points() as u64);
    assert_eq!(std::fs::metadata(d.join("a.hair")).unwrap().len(), 128 + 2 * s + 12 * n);
    assert_eq!(std::fs::metadata(d.join("b.data")).unwrap().len(), 4 + 4 * s + 12 * n);
    // Only the five outputs are in the folder: no temporary files remain.
    assert_eq!(std::fs::read_dir(&d).unwrap().count(), 5);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn hair_keeps_per_point_arrays_and_errors_name_the_file() {
    let d = tmp_dir("hair");
    let strands = random_strands(5, 20);
    let n = strands.num_points();
    let mut h = HairFile::from(strands);
    h.thickness = Some((0..n).map(|i| i as f32 * 1e-3).collect());
    h.transparency = Some(vec![0.25; n]);
    h.color = Some((0..n).map(|i| [i as f32, 0.5, 1.0]).collect());
    h.default_color = [0.1, 0.2, 0.3];
    h.info = "test file".into();
    let p = d.join("h.hair");
    write_hair(&p, &h).unwrap();
    assert_eq!(read_hair(&p, StrandReadOptions::default()).unwrap(), h);
    // A per-point array of the wrong length is refused and nothing is written.
    h.thickness.as_mut().unwrap().pop();
    let q = d.join("bad.hair");
    let e = write_hair(&q, &h).unwrap_err();
    assert!(matches!(e.kind, FormatErrorKind::CountMismatch { .. }), "{e}");
    assert!(!q.exists());
    // Truncate the good file: the error names it.
    let bytes = std::fs::read(&p).unwrap();
    std::fs::write(&q, &bytes[..bytes.len() - 4]).unwrap();
    let e = read_strands(&q).unwrap_err();
    assert_eq!(e.path.as_deref(), Some(q.as_path()));
    assert!(e.to_string().starts_with(&q.display().to_string()), "{e}");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn usc_short_strands_through_the_path_api() {
    let d = tmp_dir("usc");
    // 3 strands: 2 points, 1 point (a bald scalp sample), 3 points.
    let mut b = 3i32.to_le_bytes().to_vec();
    for (k, base) in [(2i32, 0.0f32), (1, 10.0), (3, 20.0)] {
        b.extend_from_slice(&k.to_le_bytes());
        for j in 0..k {
            for c in [base + j as f32, 0.0, 1.0] {
                b.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    let p = d.join("s.data");
    std::fs::write(&p, &b).unwrap();
    let e = read_strands(&p).unwrap_err();
    assert!(matches!(e.kind, FormatErrorKind::ShortStrand { strand: 1, count: 1, .. }), "{e}");
    let (s, skipped) = read_strands_with(&p, StrandReadOptions { skip_short_strands: true }).unwrap();
    assert_eq!((s.counts(), skipped), (&[2u32, 3][..], 1));
    assert_eq!(s.strand(1)[0], Vec3::new(20.0, 0.0, 1.0));
    std::fs::remove_dir_all(&d).unwrap();
}
