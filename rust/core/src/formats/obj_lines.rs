//! Strands as Wavefront OBJ lines: `v x y z` points and one `l i j k ...` record per strand.
//!
//! Reference: Wavefront Technologies, "Object Files (.obj)", appendix B1, the `l` (line) element
//! (<https://paulbourke.net/dataformats/obj/>).
//!
//! Each `l` record is one strand, root first; `v/vt` corner forms and negative indices are accepted,
//! and strands may share points. An `l` with fewer than two points is an error. Other records are
//! ignored. The writer prints floats in Rust's shortest round-trip form, so points read back exactly.

use glam::Vec3;

use super::obj::{floats, resolve, syntax};
use super::{FormatError, FormatErrorKind, Result};
use crate::strands::StrandSet;

/// Reads strands from OBJ bytes.
pub fn read_obj_lines_bytes(bytes: &[u8]) -> Result<StrandSet> {
    let text = std::str::from_utf8(bytes)
        .map_err(|e| FormatError::from(FormatErrorKind::Invalid(format!("the OBJ file is not UTF-8 text: {e}"))))?;
    let mut v: Vec<Vec3> = Vec::new();
    let mut points = Vec::new();
    let mut counts = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let mut f = raw.split('#').next().unwrap_or("").split_ascii_whitespace();
        match f.next() {
            Some("v") => v.push(Vec3::from(floats::<3>(&mut f, 3, line, "vertex")?)),
            Some("l") => {
                let start = points.len();
                for c in f {
                    let k = resolve(c.split('/').next().unwrap_or(""), v.len(), line, "vertex")?;
                    points.push(v[k as usize]);
                }
                let k = points.len() - start;
                if k < 2 {
                    return Err(FormatErrorKind::ShortStrand {
                        strand: counts.len() as u64,
                        count: k as u64,
                        hint: "",
                    }
                    .into());
                }
                counts.push(k as u32);
            }
            _ => {}
        }
    }
    if counts.is_empty() && !v.is_empty() {
        return Err(syntax(0, "the file has points but no `l` records; it is not a strand file"));
    }
    Ok(StrandSet::new(points, counts)?)
}

/// Writes strands as OBJ lines.
pub fn write_obj_lines_bytes(strands: &StrandSet) -> Vec<u8> {
    use std::fmt::Write as _;
    let mut s = String::with_capacity(40 * strands.num_points() + 8 * strands.num_points());
    s.push_str("# hairrecon strands: one `l` per strand, root first\n");
    for p in strands.points() {
        let _ = writeln!(s, "v {} {} {}", p.x, p.y, p.z);
    }
    for w in strands.offsets().windows(2) {
        s.push('l');
        for i in w[0]..w[1] {
            let _ = write!(s, " {}", i + 1);
        }
        s.push('\n');
    }
    s.into_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_negative_indices_and_exact_round_trip() {
        let src = "v 0 0 0\nv 1 0 0\nv 2 0 0\nl 1 2 3\nv 5 5 5\nl -1 -4\n";
        let s = read_obj_lines_bytes(src.as_bytes()).unwrap();
        assert_eq!(s.counts(), &[3, 2]);
        assert_eq!(s.strand(1), &[Vec3::splat(5.0), Vec3::ZERO]);
        let e = read_obj_lines_bytes(b"v 0 0 0\nl 1\n").unwrap_err();
        assert!(matches!(e.kind, FormatErrorKind::ShortStrand { count: 1, .. }), "{e}");
        let s = StrandSet::new(vec![Vec3::new(0.1, 1.0 / 3.0, -7e-9), Vec3::new(1e30, 2.5, 0.0)], vec![2]).unwrap();
        assert_eq!(read_obj_lines_bytes(&write_obj_lines_bytes(&s)).unwrap(), s);
    }
}
