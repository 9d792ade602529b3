//! Strands as PLY polylines: a `vertex` element (`x y z`) and an `edge` element (`vertex1 vertex2`).
//!
//! Reference: Greg Turk, "The PLY Polygon File Format" (1994), whose example declares the `edge`
//! element with `vertex1`/`vertex2` (<https://paulbourke.net/dataformats/ply/>); the parser is
//! [`super::ply::read_ply`], so ASCII and both binary byte orders are read.
//!
//! Each edge goes from a point to the next point of its strand, root to tip. The writer stores the
//! points strand after strand (binary little-endian, `float` coordinates, `int` indices). The reader
//! rebuilds polylines by chaining edges: a point with two outgoing or two incoming edges (branching,
//! or edges not oriented root to tip), a self-loop, a closed loop and a point on no edge are errors.
//! Strands come out ordered by the index of their root.

use super::ply::{read_ply, to_index, vec3s};
use super::{FormatError, FormatErrorKind, Result};
use crate::strands::StrandSet;

fn invalid(msg: String) -> FormatError {
    FormatErrorKind::Invalid(msg).into()
}

/// Reads strands from PLY polyline bytes.
pub fn read_ply_strands_bytes(bytes: &[u8]) -> Result<StrandSet> {
    let data = read_ply(bytes, |el, p| match el {
        "vertex" => matches!(p, "x" | "y" | "z"),
        "edge" => matches!(p, "vertex1" | "vertex2"),
        _ => false,
    })?;
    let vert = data.element("vertex").ok_or_else(|| invalid("the PLY file has no `vertex` element".into()))?;
    let points = vec3s(vert, ["x", "y", "z"], "point")?
        .ok_or_else(|| invalid("the PLY `vertex` element lacks x, y or z".into()))?;
    let edge = data.element("edge").ok_or_else(|| {
        invalid("the PLY file has no `edge` element; it is not a polyline file (a mesh? read it with read_mesh)".into())
    })?;
    let (Some(a), Some(b)) = (edge.scalar("vertex1"), edge.scalar("vertex2")) else {
        return Err(invalid("the PLY `edge` element lacks vertex1 or vertex2".into()));
    };
    let n = points.len();
    const NONE: u32 = u32::MAX;
    let mut next = vec![NONE; n];
    let mut prev = vec![NONE; n];
    for e in 0..a.len() {
        let (i, j) = (to_index(a[e], "edge", e, n)?, to_index(b[e], "edge", e, n)?);
        if i == j {
            return Err(invalid(format!("edge {e} joins point {i} to itself")));
        }
        if next[i as usize] != NONE || prev[j as usize] != NONE {
            let p = if next[i as usize] != NONE { i } else { j };
            return Err(invalid(format!(
                "edge {e} ({i} -> {j}) branches at point {p}: strands must be simple polylines with edges \
                 oriented root to tip"
            )));
        }
        next[i as usize] = j;
        prev[j as usize] = i;
    }
    let mut out = Vec::with_capacity(n);
    let mut counts = Vec::new();
    for r in 0..n {
        if prev[r] != NONE {
            continue;
        }
        if next[r] == NONE {
            return Err(FormatErrorKind::ShortStrand {
                strand: counts.len() as u64,
                count: 1,
                hint: " (a point on no edge)",
            }
            .into());
        }
        let start = out.len();
        let mut k = r as u32;
        while k != NONE {
            out.push(points[k as usize]);
            k = next[k as usize];
        }
        counts.push((out.len() - start) as u32);
    }
    if out.len() != n {
        return Err(invalid(format!(
            "{} points lie on closed loops; strands must have a root and a tip",
            n - out.len()
        )));
    }
    Ok(StrandSet::new(out, counts)?)
}

/// Writes strands as binary little-endian PLY polylines.
pub fn write_ply_strands_bytes(strands: &StrandSet) -> Vec<u8> {
    let n = strands.num_points();
    let ne = n - strands.num_strands();
    let h = format!(
        "ply\nformat binary_little_endian 1.0\ncomment hairrecon strands: edges go root to tip\n\
         element vertex {n}\nproperty float x\nproperty float y\nproperty float z\n\
         element edge {ne}\nproperty int vertex1\nproperty int vertex2\nend_header\n"
    );
    let mut out = Vec::with_capacity(h.len() + 12 * n + 8 * ne);
    out.extend_from_slice(h.as_bytes());
    for v in strands.flat_points() {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for w in strands.offsets().windows(2) {
        for i in w[0]..w[1] - 1 {
            out.extend_from_slice(&(i as i32).to_le_bytes());
            out.extend_from_slice(&(i as i32 + 1).to_le_bytes());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn ascii(edges: &str, ne: usize) -> String {
        format!(
            "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n\
             element edge {ne}\nproperty int vertex1\nproperty int vertex2\nend_header\n\
             0 0 0\n1 0 0\n2 0 0\n3 0 0\n4 0 0\n{edges}"
        )
    }

    #[test]
    fn chains_edges_in_any_order_and_rejects_branches() {
        // Strand 3 -> 1 -> 4 and strand 0 -> 2, edges shuffled.
        let s = read_ply_strands_bytes(ascii("1 4\n0 2\n3 1\n", 3).as_bytes()).unwrap();
        assert_eq!(s.counts(), &[2, 3]);
        assert_eq!(s.strand(1), &[Vec3::new(3.0, 0.0, 0.0), Vec3::X, Vec3::new(4.0, 0.0, 0.0)]);
        let e = read_ply_strands_bytes(ascii("0 1\n0 2\n3 4\n", 3).as_bytes()).unwrap_err();
        assert!(e.to_string().contains("branches at point 0"), "{e}");
        let e = read_ply_strands_bytes(ascii("0 1\n1 2\n2 0\n3 4\n", 4).as_bytes()).unwrap_err();
        assert!(e.to_string().contains("closed loops"), "{e}");
        let e = read_ply_strands_bytes(ascii("0 1\n1 2\n", 2).as_bytes()).unwrap_err();
        assert!(matches!(e.kind, FormatErrorKind::ShortStrand { .. }), "{e}");
        let s = StrandSet::new((0..5).map(|i| Vec3::splat(i as f32)).collect(), vec![3, 2]).unwrap();
        assert_eq!(read_ply_strands_bytes(&write_ply_strands_bytes(&s)).unwrap(), s);
    }
}
