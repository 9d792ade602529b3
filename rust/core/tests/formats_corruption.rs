//! Seeded corruption of valid files: every reader must return `Ok` or a typed `Err`, never panic,
//! never abort on a huge allocation. 10,000 cases per reader (byte flips, truncations, insertions,
//! header field changes), then specific corruptions that must give specific error variants.

use std::panic::{catch_unwind, AssertUnwindSafe};

use glam::{Vec2, Vec3};
use hairrecon_core::formats::*;
use hairrecon_core::{StrandSet, TriMesh};

const CASES: usize = 10_000;

/// A seeded xorshift generator.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Values that break counts: zero, one, sign bits, maxima.
const NASTY: [u32; 8] = [0, 1, 2, 0x7fff_ffff, 0x8000_0000, 0xffff_ffff, 0xffff, 1_000_000_000];

/// Where a reader keeps its numeric header fields.
enum Fields {
    /// Byte offsets of little-endian u32 fields.
    Binary(&'static [usize]),
    /// Digits in the text before `end_header` (PLY) or anywhere (OBJ).
    Text,
}

fn mutate(rng: &mut Rng, valid: &[u8], fields: &Fields) -> (Vec<u8>, String) {
    let mut b = valid.to_vec();
    let len = b.len();
    match rng.below(5) {
        0 => {
            let k = 1 + rng.below(4);
            for _ in 0..k {
                let i = rng.below(len);
                b[i] = rng.next() as u8;
            }
            (b, format!("{k} byte flips"))
        }
        1 => {
            let cut = rng.below(len);
            b.truncate(cut);
            (b, format!("truncated to {cut}"))
        }
        2 => {
            let at = rng.below(len + 1);
            let k = 1 + rng.below(16);
            let ins: Vec<u8> = (0..k).map(|_| rng.next() as u8).collect();
            b.splice(at..at, ins);
            (b, format!("{k} bytes inserted at {at}"))
        }
        3 => {
            // Remove a run of bytes.
            let at = rng.below(len);
            let k = (1 + rng.below(16)).min(len - at);
            b.drain(at..at + k);
            (b, format!("{k} bytes removed at {at}"))
        }
        _ => match fields {
            Fields::Binary(offsets) => {
                let off = offsets[rng.below(offsets.len())];
                let v = if rng.below(2) == 0 { NASTY[rng.below(NASTY.len())] } else { rng.next() as u32 };
                b[off..off + 4].copy_from_slice(&v.to_le_bytes());
                (b, format!("u32 at {off} set to {v}"))
            }
            Fields::Text => {
                let end = b.windows(10).position(|w| w == b"end_header").unwrap_or(len);
                let runs: Vec<(usize, usize)> = digit_runs(&b[..end]);
                if runs.is_empty() {
                    return (b, "no field".into());
                }
                let (s, e) = runs[rng.below(runs.len())];
                let v = match rng.below(4) {
                    0 => NASTY[rng.below(NASTY.len())].to_string(),
                    1 => "18446744073709551615".to_string(),
                    2 => "99999999999999999999999".to_string(),
                    _ => (rng.next() % 1000).to_string(),
                };
                b.splice(s..e, v.bytes());
                (b, format!("field at {s} set to {v}"))
            }
        },
    }
}

fn digit_runs(b: &[u8]) -> Vec<(usize, usize)> {
    let mut runs = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i].is_ascii_digit() {
            let s = i;
            while i < b.len() && b[i].is_ascii_digit() {
                i += 1;
            }
            runs.push((s, i));
        } else {
            i += 1;
        }
    }
    runs
}

/// Runs `CASES` corruptions of `valid` through `read`; panics (failing the test) if any case panics.
fn fuzz<T>(name: &str, seed: u64, valid: &[u8], fields: Fields, read: impl Fn(&[u8]) -> Result<T, FormatError>) {
    assert!(read(valid).is_ok(), "{name}: the valid file does not read");
    let mut rng = Rng(seed);
    let (mut ok, mut err) = (0, 0);
    for case in 0..CASES {
        let (bytes, what) = mutate(&mut rng, valid, &fields);
        match catch_unwind(AssertUnwindSafe(|| read(&bytes).map(|_| ()))) {
            Ok(Ok(())) => ok += 1,
            Ok(Err(e)) => {
                // Every error has a message.
                assert!(!e.to_string().is_empty());
                err += 1;
            }
            Err(_) => panic!("{name}: case {case} (seed {seed}: {what}) panicked"),
        }
    }
    println!("{name}: {CASES} corruptions, {ok} read, {err} rejected");
    assert!(err > CASES / 2, "{name}: only {err} corruptions rejected");
}

fn strands() -> StrandSet {
    let mut points = Vec::new();
    let mut counts = Vec::new();
    for s in 0..12u32 {
        let k = 2 + s % 7;
        for j in 0..k {
            points.push(Vec3::new(s as f32 * 0.01, j as f32 * 0.002, 0.1 + (s * j) as f32 * 1e-4));
        }
        counts.push(k);
    }
    StrandSet::new(points, counts).unwrap()
}

fn mesh() -> TriMesh {
    let n = 6u32;
    let mut v = Vec::new();
    let mut uv = Vec::new();
    for i in 0..n {
        for j in 0..n {
            v.push(Vec3::new(i as f32, j as f32, ((i * j) % 3) as f32 * 0.1));
            uv.push(Vec2::new(i as f32 / 5.0, j as f32 / 5.0));
        }
    }
    let mut t = Vec::new();
    for i in 0..n - 1 {
        for j in 0..n - 1 {
            let a = i * n + j;
            t.push([a, a + n, a + 1]);
            t.push([a + 1, a + n, a + n + 1]);
        }
    }
    let m = TriMesh::new(v, t, None, Some(uv)).unwrap();
    let normals = m.compute_vertex_normals();
    TriMesh::new(m.vertices, m.triangles, Some(normals), m.uvs).unwrap()
}

fn ascii_ply_mesh(m: &TriMesh) -> Vec<u8> {
    let mut s = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property float u\nproperty float v\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        m.vertices.len(),
        m.triangles.len() / 2
    );
    for (p, t) in m.vertices.iter().zip(m.uvs.as_ref().unwrap()) {
        s += &format!("{} {} {} {} {}\n", p.x, p.y, p.z, t.x, t.y);
    }
    // Quads, to exercise fan triangulation.
    for q in m.triangles.chunks(2) {
        s += &format!("4 {} {} {} {}\n", q[0][0], q[0][1], q[1][2], q[0][2]);
    }
    s.into_bytes()
}

#[test]
fn hair_survives_corruption() {
    let valid = write_hair_bytes(&HairFile::from(strands())).unwrap();
    fuzz("hair", 1, &valid, Fields::Binary(&[4, 8, 12, 16]), read_hair_bytes);
}

#[test]
fn usc_survives_corruption() {
    let valid = write_usc_bytes(&strands());
    // The strand count and the first two strands' point counts (2 and 3 points).
    let opts = UscReadOptions { skip_short_strands: true };
    fuzz("usc", 2, &valid, Fields::Binary(&[0, 4, 32]), |b| read_usc_bytes(b, opts));
    fuzz("usc strict", 3, &valid, Fields::Binary(&[0, 4, 32]), |b| read_usc_bytes(b, UscReadOptions::default()));
}

#[test]
fn ply_strands_survive_corruption() {
    let valid = write_ply_strands_bytes(&strands());
    fuzz("ply strands", 4, &valid, Fields::Text, read_ply_strands_bytes);
}

#[test]
fn obj_lines_survive_corruption() {
    let valid = write_obj_lines_bytes(&strands());
    fuzz("obj lines", 5, &valid, Fields::Text, read_obj_lines_bytes);
}

#[test]
fn ply_meshes_survive_corruption() {
    let m = mesh();
    fuzz("ply mesh binary", 6, &write_ply_mesh_bytes(&m), Fields::Text, read_ply_mesh_bytes);
    fuzz("ply mesh ascii", 7, &ascii_ply_mesh(&m), Fields::Text, read_ply_mesh_bytes);
}

#[test]
fn obj_mesh_survives_corruption() {
    fuzz("obj mesh", 8, &write_obj_bytes(&mesh()), Fields::Text, read_obj_bytes);
}

/// The error kind of reading `bytes`, which must fail.
fn kind<T: std::fmt::Debug>(r: Result<T, FormatError>) -> FormatErrorKind {
    r.expect_err("this corruption must be rejected").kind
}

fn set_u32(b: &mut [u8], off: usize, v: u32) {
    b[off..off + 4].copy_from_slice(&v.to_le_bytes());
}

#[test]
fn hair_corruptions_give_the_expected_errors() {
    let valid = write_hair_bytes(&HairFile::from(strands())).unwrap();
    let mut b = valid.clone();
    b[0] = b'X';
    assert!(matches!(kind(read_hair_bytes(&b)), FormatErrorKind::BadMagic { .. }));
    assert!(matches!(kind(read_hair_bytes(&valid[..100])), FormatErrorKind::Truncated { .. }));
    // Absurd strand count: 4 billion u16 would be 8 GB; refused against the file length.
    let mut b = valid.clone();
    set_u32(&mut b, 4, u32::MAX);
    assert!(matches!(kind(read_hair_bytes(&b)), FormatErrorKind::CountTooLarge { count: 4294967295, .. }));
    // A point count that disagrees with the segments.
    let mut b = valid.clone();
    set_u32(&mut b, 8, u32::MAX);
    assert!(matches!(kind(read_hair_bytes(&b)), FormatErrorKind::CountMismatch { found: 4294967295, .. }));
    // No points array.
    let mut b = valid.clone();
    set_u32(&mut b, 12, 1);
    assert!(matches!(kind(read_hair_bytes(&b)), FormatErrorKind::Header(_)));
    // Truncated data and extra data.
    assert!(matches!(kind(read_hair_bytes(&valid[..valid.len() - 1])), FormatErrorKind::CountTooLarge { .. }));
    let mut b = valid.clone();
    b.push(0);
    assert!(matches!(kind(read_hair_bytes(&b)), FormatErrorKind::TrailingBytes { count: 1, .. }));
    // NaN and infinity in a point: the second point's y (header, 12 u16 segment counts, 1 point, x).
    for v in [f32::NAN, f32::INFINITY] {
        let mut b = valid.clone();
        let off = 128 + 24 + 12 + 4;
        b[off..off + 4].copy_from_slice(&v.to_le_bytes());
        assert!(matches!(kind(read_hair_bytes(&b)), FormatErrorKind::NotFinite { index: 1, .. }));
    }
    // A strand of one point (0 segments) ...
    let mut b = valid.clone();
    b[128..130].copy_from_slice(&0u16.to_le_bytes());
    b[130..132].copy_from_slice(&(2u16 + 1).to_le_bytes()); // keep the total: strand 1 grows by one
    assert!(matches!(kind(read_hair_bytes(&b)), FormatErrorKind::ShortStrand { strand: 0, count: 1, .. }));
}

#[test]
fn usc_corruptions_give_the_expected_errors() {
    let valid = write_usc_bytes(&strands());
    let d = UscReadOptions::default();
    let mut b = valid.clone();
    set_u32(&mut b, 0, u32::MAX); // -1 strands
    assert!(matches!(kind(read_usc_bytes(&b, d)), FormatErrorKind::Header(_)));
    let mut b = valid.clone();
    set_u32(&mut b, 0, 0x7fff_ffff);
    assert!(matches!(kind(read_usc_bytes(&b, d)), FormatErrorKind::CountTooLarge { count: 2147483647, .. }));
    let mut b = valid.clone();
    set_u32(&mut b, 4, 0x7fff_ffff); // the first strand claims 2 billion points (24 GB)
    assert!(matches!(kind(read_usc_bytes(&b, d)), FormatErrorKind::CountTooLarge { count: 2147483647, .. }));
    let mut b = valid.clone();
    set_u32(&mut b, 4, 0x8000_0000);
    assert!(matches!(kind(read_usc_bytes(&b, d)), FormatErrorKind::Invalid(_)));
    assert!(matches!(kind(read_usc_bytes(&valid[..2], d)), FormatErrorKind::Truncated { .. }));
    let mut b = valid.clone();
    b.extend_from_slice(&[1, 2, 3]);
    assert!(matches!(kind(read_usc_bytes(&b, d)), FormatErrorKind::TrailingBytes { count: 3, .. }));
    let mut b = valid.clone();
    b[8..12].copy_from_slice(&f32::NEG_INFINITY.to_le_bytes());
    assert!(matches!(kind(read_usc_bytes(&b, d)), FormatErrorKind::NotFinite { index: 0, .. }));
}

#[test]
fn ply_and_obj_corruptions_give_the_expected_errors() {
    let set = strands();
    let (nv, ne) = (set.num_points(), set.num_points() - set.num_strands());
    assert_eq!((nv, ne), (55, 43));
    let valid = write_ply_strands_bytes(&set);
    // Replace text in the header, keeping the binary body byte for byte.
    let swap = |from: &str, to: &str| {
        let at = valid.windows(from.len()).position(|w| w == from.as_bytes()).expect(from);
        let mut b = valid.clone();
        b.splice(at..at + from.len(), to.bytes());
        b
    };
    let huge = swap("element vertex 55", "element vertex 18446744073709551615");
    assert!(matches!(kind(read_ply_strands_bytes(&huge)), FormatErrorKind::CountTooLarge { .. }));
    let overflow = swap("element vertex 55", "element vertex 99999999999999999999999");
    assert!(matches!(kind(read_ply_strands_bytes(&overflow)), FormatErrorKind::Header(_)));
    assert!(matches!(kind(read_ply_strands_bytes(&swap("ply\n", "plz\n"))), FormatErrorKind::BadMagic { .. }));
    let fewer = swap("element edge 43", "element edge 42");
    let k = kind(read_ply_strands_bytes(&fewer));
    assert!(matches!(k, FormatErrorKind::TrailingBytes { count: 8, .. }), "{k}");
    let mut b = valid.clone();
    let n = b.len();
    b[n - 4..].copy_from_slice(&1000i32.to_le_bytes()); // the last edge's vertex2
    assert!(matches!(kind(read_ply_strands_bytes(&b)), FormatErrorKind::IndexOutOfRange { value: 1000, .. }));
    let mut b = valid.clone();
    b[n - 4..].copy_from_slice(&1i32.to_le_bytes()); // point 1 gets a second incoming edge
    let k = kind(read_ply_strands_bytes(&b));
    assert!(matches!(&k, FormatErrorKind::Invalid(m) if m.contains("branches at point 1")), "{k}");
    b[n - 4..].copy_from_slice(&0i32.to_le_bytes()); // joins strand 11 to strand 0, orphaning point 54
    assert!(matches!(kind(read_ply_strands_bytes(&b)), FormatErrorKind::ShortStrand { count: 1, .. }));
    assert!(matches!(kind(read_ply_mesh_bytes(&valid)), FormatErrorKind::Mesh(_))); // polylines have no faces

    let obj = String::from_utf8(write_obj_lines_bytes(&strands())).unwrap();
    let bad = obj.replacen("l 1 2", "l 1 999", 1);
    assert!(matches!(kind(read_obj_lines_bytes(bad.as_bytes())), FormatErrorKind::Syntax { .. }));
    let bad = obj.replacen("l 1 2", "l 1", 1);
    assert!(matches!(kind(read_obj_lines_bytes(bad.as_bytes())), FormatErrorKind::ShortStrand { strand: 0, .. }));
}
