//! Wavefront OBJ triangle meshes: `v`, `vt`, `vn` and `f` records.
//!
//! Reference: Wavefront Technologies, "Object Files (.obj)", Advanced Visualizer manual, appendix B1
//! (<https://paulbourke.net/dataformats/obj/>).
//!
//! Faces may use the `v`, `v/vt`, `v//vn` and `v/vt/vn` corner forms and negative (relative)
//! indices; polygons are fan-triangulated. OBJ attaches UVs and normals to face corners while
//! [`TriMesh`] keeps one per vertex: each vertex takes the `vt` (and `vn`) of the first corner that
//! uses it. UVs (normals) are kept only if every corner has one. Other records (`o`, `g`, `s`,
//! `usemtl`, `mtllib`, `l`, `p`, ...) are ignored. The writer prints floats in Rust's shortest
//! round-trip form, so a written mesh reads back bit-exactly.

use std::io::Write;

use glam::{Vec2, Vec3};

use super::{FormatError, FormatErrorKind, Result};
use crate::mesh::TriMesh;

pub(crate) fn syntax(line: usize, msg: impl Into<String>) -> FormatError {
    FormatErrorKind::Syntax { line: line as u64, msg: msg.into() }.into()
}

/// Parses `n` finite floats (at least `min` of them, missing ones 0) from the fields of a record.
pub(crate) fn floats<const N: usize>(
    fields: &mut std::str::SplitAsciiWhitespace<'_>,
    min: usize,
    line: usize,
    what: &'static str,
) -> Result<[f32; N]> {
    let mut out = [0.0f32; N];
    for (k, o) in out.iter_mut().enumerate() {
        match fields.next() {
            Some(t) => {
                let v: f32 = t.parse().map_err(|_| syntax(line, format!("{what}: {t:?} is not a number")))?;
                if !v.is_finite() {
                    return Err(syntax(line, format!("{what}: {t:?} is not finite; remove NaN or infinite values")));
                }
                *o = v;
            }
            None if k >= min => break,
            None => return Err(syntax(line, format!("{what}: {min} numbers expected"))),
        }
    }
    Ok(out)
}

/// Resolves a 1-based (or negative, relative) OBJ index against `count` items defined so far.
pub(crate) fn resolve(tok: &str, count: usize, line: usize, what: &'static str) -> Result<u32> {
    let i: i64 = tok.parse().map_err(|_| syntax(line, format!("{what} index {tok:?} is not an integer")))?;
    let r = if i > 0 { i - 1 } else { count as i64 + i };
    if i == 0 || r < 0 || r >= count as i64 {
        return Err(syntax(line, format!("{what} index {i} is out of range: {count} defined so far")));
    }
    Ok(r as u32)
}

/// Reads a triangle mesh from OBJ bytes.
pub fn read_obj_bytes(bytes: &[u8]) -> Result<TriMesh> {
    let text = std::str::from_utf8(bytes)
        .map_err(|e| FormatError::from(FormatErrorKind::Invalid(format!("the OBJ file is not UTF-8 text: {e}"))))?;
    let mut v: Vec<Vec3> = Vec::new();
    let mut vt: Vec<Vec2> = Vec::new();
    let mut vn: Vec<Vec3> = Vec::new();
    // Corners: (vertex, uv, normal), u32::MAX where absent.
    let mut corners: Vec<[u32; 3]> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut face: Vec<[u32; 3]> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let body = raw.split('#').next().unwrap_or("");
        let mut f = body.split_ascii_whitespace();
        match f.next() {
            Some("v") => v.push(Vec3::from(floats::<3>(&mut f, 3, line, "vertex")?)),
            Some("vt") => {
                let [a, b] = floats::<2>(&mut f, 1, line, "texture coordinate")?;
                vt.push(Vec2::new(a, b));
            }
            Some("vn") => vn.push(Vec3::from(floats::<3>(&mut f, 3, line, "normal")?)),
            Some("f") => {
                face.clear();
                for c in f {
                    let mut parts = c.split('/');
                    let vi = resolve(parts.next().unwrap_or(""), v.len(), line, "vertex")?;
                    let ti = match parts.next() {
                        Some("") | None => u32::MAX,
                        Some(t) => resolve(t, vt.len(), line, "texture coordinate")?,
                    };
                    let ni = match parts.next() {
                        Some("") | None => u32::MAX,
                        Some(t) => resolve(t, vn.len(), line, "normal")?,
                    };
                    if parts.next().is_some() {
                        return Err(syntax(line, format!("face corner {c:?} has more than three parts")));
                    }
                    face.push([vi, ti, ni]);
                }
                if face.len() < 3 {
                    return Err(syntax(line, format!("a face has {} corner(s); at least 3 are needed", face.len())));
                }
                for k in 1..face.len() - 1 {
                    triangles.push([face[0][0], face[k][0], face[k + 1][0]]);
                }
                corners.extend_from_slice(&face);
            }
            _ => {}
        }
    }
    // Per-vertex attributes from the first corner that uses each vertex.
    let attr = |slot: usize| -> Option<Vec<u32>> {
        if corners.iter().any(|c| c[slot] == u32::MAX) {
            return None;
        }
        let mut first = vec![u32::MAX; v.len()];
        for c in &corners {
            if first[c[0] as usize] == u32::MAX {
                first[c[0] as usize] = c[slot];
            }
        }
        Some(first)
    };
    let uvs = if vt.is_empty() {
        None
    } else {
        attr(1).map(|f| f.iter().map(|&k| vt.get(k as usize).copied().unwrap_or(Vec2::ZERO)).collect())
    };
    let normals = if vn.is_empty() {
        None
    } else {
        attr(2).map(|f| f.iter().map(|&k| vn.get(k as usize).copied().unwrap_or(Vec3::ZERO)).collect())
    };
    Ok(TriMesh::new(v, triangles, normals, uvs)?)
}

/// Writes a mesh as OBJ, with `vt`/`vn` per vertex when the mesh has UVs/normals.
pub fn write_obj<W: Write>(w: &mut W, mesh: &TriMesh) -> Result<()> {
    let mut s = String::with_capacity(mesh.vertices.len() * 40 + mesh.triangles.len() * 30);
    s.push_str("# written by hairrecon\n");
    use std::fmt::Write as _;
    for p in &mesh.vertices {
        let _ = writeln!(s, "v {} {} {}", p.x, p.y, p.z);
    }
    if let Some(uv) = &mesh.uvs {
        for t in uv {
            let _ = writeln!(s, "vt {} {}", t.x, t.y);
        }
    }
    if let Some(n) = &mesh.normals {
        for p in n {
            let _ = writeln!(s, "vn {} {} {}", p.x, p.y, p.z);
        }
    }
    for t in &mesh.triangles {
        s.push('f');
        for &i in t {
            let i = i + 1;
            let _ = match (mesh.uvs.is_some(), mesh.normals.is_some()) {
                (false, false) => write!(s, " {i}"),
                (true, false) => write!(s, " {i}/{i}"),
                (false, true) => write!(s, " {i}//{i}"),
                (true, true) => write!(s, " {i}/{i}/{i}"),
            };
        }
        s.push('\n');
    }
    w.write_all(s.as_bytes())?;
    Ok(())
}

/// Writes a mesh as OBJ into memory.
pub fn write_obj_bytes(mesh: &TriMesh) -> Vec<u8> {
    let mut out = Vec::new();
    let _ = write_obj(&mut out, mesh);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corner_forms_negative_indices_and_first_corner_uvs() {
        let src = "# quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.5\n\
                   o thing\nf 1/1 2/2 3/3 4/4\nf -4/5 -2/3 -1/4 # reuses vertex 1 with another vt\n";
        let m = read_obj_bytes(src.as_bytes()).unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 2, 3]]);
        let uv = m.uvs.unwrap();
        assert_eq!(uv[0], Vec2::ZERO, "the first corner's vt wins");
        assert_eq!(uv[2], Vec2::ONE);
        assert!(m.normals.is_none());
        let e = read_obj_bytes(b"v 0 0 0\nv 1 0 0\nf 1 2 3\n").unwrap_err();
        assert!(matches!(e.kind, FormatErrorKind::Syntax { line: 3, .. }), "{e}");
        let e = read_obj_bytes(b"v 0 0 nan\n").unwrap_err();
        assert!(matches!(e.kind, FormatErrorKind::Syntax { line: 1, .. }), "{e}");
    }

    #[test]
    fn round_trip_is_exact() {
        let v = vec![Vec3::new(0.1, -2.5e-7, 3.0), Vec3::new(1.0 / 3.0, 0.0, 0.0), Vec3::new(0.0, 7.0, 1e20)];
        let n = vec![Vec3::Z, Vec3::X, Vec3::new(0.6, 0.8, 0.0)];
        let uv = vec![Vec2::new(0.25, 0.75), Vec2::ZERO, Vec2::new(1.0 / 7.0, 0.5)];
        for (nn, uu) in [(None, None), (Some(n.clone()), None), (None, Some(uv.clone())), (Some(n), Some(uv))] {
            let m = TriMesh::new(v.clone(), vec![[0, 1, 2]], nn, uu).unwrap();
            assert_eq!(read_obj_bytes(&write_obj_bytes(&m)).unwrap(), m);
        }
    }
}
