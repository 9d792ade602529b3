//! PLY (Stanford polygon file format): a general reader and triangle-mesh read/write.
//!
//! Reference: Greg Turk, "The PLY Polygon File Format" (1994),
//! <https://paulbourke.net/dataformats/ply/>.
//!
//! [`read_ply`] parses ASCII, binary little-endian and binary big-endian files with any elements and
//! properties (all eight scalar types, lists with any integer count type), keeping only the
//! properties the caller asks for and skipping the rest byte-exactly. [`read_ply_mesh_bytes`] builds a
//! [`TriMesh`] from the `vertex` element (`x y z`, optional `nx ny nz`, optional UVs named `s t`,
//! `u v`, `texture_u texture_v` or `texture_s texture_t`) and the `face` element (`vertex_indices` or
//! `vertex_index` lists, polygons fan-triangulated). [`write_ply_mesh`] writes binary little-endian
//! with `float` attributes and `uchar`/`uint` face lists, as Blender does.

use std::io::Write;

use glam::{Vec2, Vec3};

use super::bytes::{Cursor, Endian};
use super::{FormatError, FormatErrorKind, Result};
use crate::mesh::TriMesh;

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScalarType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl ScalarType {
    /// Parses a type name, old (`uchar`) or new (`uint8`) style.
    pub fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    /// Size in bytes in a binary file.
    pub fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Self::F32 | Self::F64)
    }

    /// The range of an integer type.
    fn range(self) -> (f64, f64) {
        match self {
            Self::I8 => (i8::MIN as f64, i8::MAX as f64),
            Self::U8 => (0.0, u8::MAX as f64),
            Self::I16 => (i16::MIN as f64, i16::MAX as f64),
            Self::U16 => (0.0, u16::MAX as f64),
            Self::I32 => (i32::MIN as f64, i32::MAX as f64),
            Self::U32 => (0.0, u32::MAX as f64),
            Self::F32 | Self::F64 => (f64::NEG_INFINITY, f64::INFINITY),
        }
    }
}

/// The encoding of a PLY body.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlyFormat {
    Ascii,
    Binary(Endian),
}

/// A property: a scalar or a list.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PropertyKind {
    Scalar(ScalarType),
    List { count: ScalarType, item: ScalarType },
}

/// A property declaration.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PropertyDef {
    pub name: String,
    pub kind: PropertyKind,
}

/// An element declaration.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ElementDef {
    pub name: String,
    pub count: u64,
    pub properties: Vec<PropertyDef>,
}

/// A parsed PLY header.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlyHeader {
    pub format: PlyFormat,
    pub elements: Vec<ElementDef>,
    pub comments: Vec<String>,
}

/// The values of one property over all rows of an element.
#[derive(Debug, Clone, PartialEq)]
pub enum Column {
    Scalar(Vec<f64>),
    /// Row `i` holds `values[offsets[i]..offsets[i + 1]]`.
    List {
        offsets: Vec<usize>,
        values: Vec<f64>,
    },
}

/// The kept properties of one element.
#[derive(Debug, Clone, PartialEq)]
pub struct ElementData {
    pub name: String,
    pub count: usize,
    pub columns: Vec<(String, Column)>,
}

impl ElementData {
    /// The values of a scalar property, if it was kept.
    pub fn scalar(&self, name: &str) -> Option<&[f64]> {
        self.columns.iter().find_map(|(n, c)| match c {
            Column::Scalar(v) if n == name => Some(v.as_slice()),
            _ => None,
        })
    }

    /// The offsets and values of a list property, if it was kept.
    pub fn list(&self, name: &str) -> Option<(&[usize], &[f64])> {
        self.columns.iter().find_map(|(n, c)| match c {
            Column::List { offsets, values } if n == name => Some((offsets.as_slice(), values.as_slice())),
            _ => None,
        })
    }
}

/// A parsed PLY file: its header and the kept properties of every element, in file order.
#[derive(Debug, Clone, PartialEq)]
pub struct PlyData {
    pub header: PlyHeader,
    pub elements: Vec<ElementData>,
}

impl PlyData {
    /// The element called `name`, if any.
    pub fn element(&self, name: &str) -> Option<&ElementData> {
        self.elements.iter().find(|e| e.name == name)
    }
}

fn header_err(line: usize, msg: impl std::fmt::Display) -> FormatError {
    FormatErrorKind::Header(format!("PLY header line {line}: {msg}")).into()
}

/// Parses the header; returns it and the byte offset where the body starts.
pub fn parse_header(bytes: &[u8]) -> Result<(PlyHeader, usize)> {
    if !(bytes.starts_with(b"ply\n") || bytes.starts_with(b"ply\r\n")) {
        let found = String::from_utf8_lossy(&bytes[..bytes.len().min(8)]).into_owned();
        return Err(FormatErrorKind::BadMagic { format: "PLY", expected: "ply", found }.into());
    }
    let mut pos = 0usize;
    let mut format = None;
    let mut elements: Vec<ElementDef> = Vec::new();
    let mut comments = Vec::new();
    let mut line_no = 0usize;
    loop {
        line_no += 1;
        let Some(nl) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(header_err(line_no, "the file ends before `end_header`; it is truncated or not a PLY file"));
        };
        let raw = &bytes[pos..pos + nl];
        pos += nl + 1;
        let line = std::str::from_utf8(raw).map_err(|_| header_err(line_no, "the header is not ASCII text"))?;
        let line = line.trim_end_matches('\r');
        let mut tok = line.split_ascii_whitespace();
        let Some(key) = tok.next() else { continue };
        let rest: Vec<&str> = tok.collect();
        match key {
            "ply" if line_no == 1 => {}
            "comment" | "obj_info" => comments.push(line[key.len()..].trim().to_string()),
            "format" => {
                let f = match rest.first().copied() {
                    Some("ascii") => PlyFormat::Ascii,
                    Some("binary_little_endian") => PlyFormat::Binary(Endian::Little),
                    Some("binary_big_endian") => PlyFormat::Binary(Endian::Big),
                    other => return Err(header_err(line_no, format!("unknown format {other:?}"))),
                };
                if rest.get(1).is_some_and(|v| *v != "1.0") {
                    return Err(header_err(line_no, format!("unsupported PLY version {:?} (1.0 expected)", rest[1])));
                }
                format = Some(f);
            }
            "element" => {
                let [name, count] = rest[..] else {
                    return Err(header_err(line_no, "expected `element <name> <count>`"));
                };
                let count = count
                    .parse::<u64>()
                    .map_err(|_| header_err(line_no, format!("element count {count:?} is not a whole number")))?;
                elements.push(ElementDef { name: name.to_string(), count, properties: Vec::new() });
            }
            "property" => {
                let Some(el) = elements.last_mut() else {
                    return Err(header_err(line_no, "a property comes before any element"));
                };
                let ty =
                    |s: &str| ScalarType::parse(s).ok_or_else(|| header_err(line_no, format!("unknown type {s:?}")));
                let def = match rest[..] {
                    ["list", c, i, name] => {
                        let count = ty(c)?;
                        if !count.is_integer() {
                            return Err(header_err(line_no, format!("list count type {c:?} is not an integer type")));
                        }
                        PropertyDef { name: name.to_string(), kind: PropertyKind::List { count, item: ty(i)? } }
                    }
                    [t, name] => PropertyDef { name: name.to_string(), kind: PropertyKind::Scalar(ty(t)?) },
                    _ => return Err(header_err(line_no, "expected `property <type> <name>` or `property list ...`")),
                };
                el.properties.push(def);
            }
            "end_header" => break,
            other => return Err(header_err(line_no, format!("unknown keyword {other:?}"))),
        }
    }
    let format = format.ok_or_else(|| header_err(line_no, "no `format` line"))?;
    Ok((PlyHeader { format, elements, comments }, pos))
}

/// A source of values: binary or ASCII.
trait Values {
    fn value(&mut self, ty: ScalarType, what: &str) -> Result<f64>;
    fn remaining(&self) -> usize;
}

struct Binary<'a> {
    cur: Cursor<'a>,
    endian: Endian,
}

impl Values for Binary<'_> {
    fn value(&mut self, ty: ScalarType, what: &str) -> Result<f64> {
        let (c, e) = (&mut self.cur, self.endian);
        Ok(match ty {
            ScalarType::I8 => c.u8(what)? as i8 as f64,
            ScalarType::U8 => c.u8(what)? as f64,
            ScalarType::I16 => c.u16(e, what)? as i16 as f64,
            ScalarType::U16 => c.u16(e, what)? as f64,
            ScalarType::I32 => c.i32(e, what)? as f64,
            ScalarType::U32 => c.u32(e, what)? as f64,
            ScalarType::F32 => c.f32(e, what)? as f64,
            ScalarType::F64 => c.f64(e, what)?,
        })
    }

    fn remaining(&self) -> usize {
        self.cur.remaining()
    }
}

struct Ascii<'a> {
    data: &'a [u8],
    pos: usize,
    line: u64,
}

impl Ascii<'_> {
    fn token(&mut self, what: &str) -> Result<&str> {
        while self.pos < self.data.len() && self.data[self.pos].is_ascii_whitespace() {
            if self.data[self.pos] == b'\n' {
                self.line += 1;
            }
            self.pos += 1;
        }
        let start = self.pos;
        while self.pos < self.data.len() && !self.data[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        if start == self.pos {
            return Err(FormatErrorKind::Truncated {
                what: what.to_string(),
                offset: start as u64,
                needed: 1,
                len: self.data.len() as u64,
            }
            .into());
        }
        std::str::from_utf8(&self.data[start..self.pos])
            .map_err(|_| FormatErrorKind::Syntax { line: self.line, msg: format!("{what}: not ASCII text") }.into())
    }
}

impl Values for Ascii<'_> {
    fn value(&mut self, ty: ScalarType, what: &str) -> Result<f64> {
        let line = self.line;
        let tok = self.token(what)?;
        let bad = |msg: String| -> FormatError { FormatErrorKind::Syntax { line, msg }.into() };
        let v: f64 = tok.parse().map_err(|_| bad(format!("{what}: {tok:?} is not a number")))?;
        if ty.is_integer() {
            let (lo, hi) = ty.range();
            if v.fract() != 0.0 || v < lo || v > hi {
                return Err(bad(format!("{what}: {tok:?} is not a valid {ty:?} integer")));
            }
        }
        Ok(v)
    }

    fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }
}

/// Parses a PLY file, keeping the properties for which `keep(element, property)` is true.
/// Binary bodies must end exactly after the last element; ASCII bodies may end with whitespace.
pub fn read_ply(bytes: &[u8], keep: impl Fn(&str, &str) -> bool) -> Result<PlyData> {
    let (header, start) = parse_header(bytes)?;
    let body = &bytes[start..];
    let elements = match header.format {
        PlyFormat::Binary(endian) => {
            let mut src = Binary { cur: Cursor::new(body), endian };
            let els = read_body(&header, &mut src, &keep, true)?;
            src.cur.expect_end("PLY element")?;
            els
        }
        PlyFormat::Ascii => {
            let mut src =
                Ascii { data: body, pos: 0, line: bytes[..start].iter().filter(|&&b| b == b'\n').count() as u64 + 1 };
            let els = read_body(&header, &mut src, &keep, false)?;
            if src.token("end").is_ok() {
                return Err(FormatErrorKind::Syntax {
                    line: src.line,
                    msg: "values follow the last element; the element counts in the header are wrong".into(),
                }
                .into());
            }
            els
        }
    };
    Ok(PlyData { header, elements })
}

fn read_body(
    header: &PlyHeader,
    src: &mut dyn Values,
    keep: &dyn Fn(&str, &str) -> bool,
    binary: bool,
) -> Result<Vec<ElementData>> {
    let mut out = Vec::with_capacity(header.elements.len());
    for el in &header.elements {
        let kept: Vec<bool> = el.properties.iter().map(|p| keep(&el.name, &p.name)).collect();
        if el.properties.is_empty() {
            // Nothing to read, whatever the count says.
            out.push(ElementData { name: el.name.clone(), count: 0, columns: Vec::new() });
            continue;
        }
        // Smallest possible row: every scalar, and a zero count for every list (binary), or one
        // character and a separator per value (ASCII).
        let min_row: u64 = if binary {
            el.properties
                .iter()
                .map(|p| match p.kind {
                    PropertyKind::Scalar(t) => t.size() as u64,
                    PropertyKind::List { count, .. } => count.size() as u64,
                })
                .sum()
        } else {
            el.properties.len() as u64 * 2 - 1
        };
        let available = src.remaining() as u64 + if binary { 0 } else { 1 };
        let fits = matches!(el.count.checked_mul(min_row), Some(t) if t <= available);
        if !fits {
            return Err(FormatErrorKind::CountTooLarge {
                what: "PLY element rows",
                count: el.count,
                available,
                min_size: min_row,
            }
            .into());
        }
        let n = el.count as usize;
        let mut columns: Vec<(String, Column)> = el
            .properties
            .iter()
            .zip(&kept)
            .filter(|(_, &k)| k)
            .map(|(p, _)| {
                let col = match p.kind {
                    PropertyKind::Scalar(_) => Column::Scalar(Vec::with_capacity(n)),
                    PropertyKind::List { .. } => {
                        let mut offsets = Vec::with_capacity(n + 1);
                        offsets.push(0);
                        Column::List { offsets, values: Vec::new() }
                    }
                };
                (p.name.clone(), col)
            })
            .collect();
        // Descriptions for error messages, built once per element rather than per value.
        let whats: Vec<String> =
            el.properties.iter().map(|p| format!("property {:?} of element {:?}", p.name, el.name)).collect();
        for _ in 0..n {
            let mut ci = 0;
            for ((p, &k), what) in el.properties.iter().zip(&kept).zip(&whats) {
                match p.kind {
                    PropertyKind::Scalar(t) => {
                        let v = src.value(t, what)?;
                        if k {
                            if let Column::Scalar(vals) = &mut columns[ci].1 {
                                vals.push(v);
                            }
                        }
                    }
                    PropertyKind::List { count, item } => {
                        let c = src.value(count, what)?;
                        if c < 0.0 {
                            return Err(FormatErrorKind::Invalid(format!("{what}: negative list length {c}")).into());
                        }
                        let c = c as u64;
                        // Each item needs its bytes (binary) or a token (ASCII): check before looping.
                        let min_item = if binary { item.size() as u64 } else { 1 };
                        if c * min_item > src.remaining() as u64 {
                            return Err(FormatErrorKind::CountTooLarge {
                                what: "PLY list items",
                                count: c,
                                available: src.remaining() as u64,
                                min_size: min_item,
                            }
                            .into());
                        }
                        for _ in 0..c {
                            let v = src.value(item, what)?;
                            if k {
                                if let Column::List { values, .. } = &mut columns[ci].1 {
                                    values.push(v);
                                }
                            }
                        }
                        if k {
                            if let Column::List { offsets, values } = &mut columns[ci].1 {
                                offsets.push(values.len());
                            }
                        }
                    }
                }
                if k {
                    ci += 1;
                }
            }
        }
        out.push(ElementData { name: el.name.clone(), count: n, columns });
    }
    Ok(out)
}

/// Converts a value read from a file to an index below `count`.
pub(crate) fn to_index(v: f64, what: &'static str, index: usize, count: usize) -> Result<u32> {
    if v.fract() == 0.0 && v >= 0.0 && v < count as f64 && v <= u32::MAX as f64 {
        Ok(v as u32)
    } else {
        Err(FormatErrorKind::IndexOutOfRange { what, index: index as u64, value: v as i64, count: count as u64 }.into())
    }
}

/// Gathers three scalar columns into finite vectors.
pub(crate) fn vec3s(el: &ElementData, names: [&str; 3], what: &'static str) -> Result<Option<Vec<Vec3>>> {
    let (Some(x), Some(y), Some(z)) = (el.scalar(names[0]), el.scalar(names[1]), el.scalar(names[2])) else {
        return Ok(None);
    };
    let mut out = Vec::with_capacity(x.len());
    for i in 0..x.len() {
        let v = Vec3::new(x[i] as f32, y[i] as f32, z[i] as f32);
        if !v.is_finite() {
            let bad = [x[i], y[i], z[i]].into_iter().find(|c| !(*c as f32).is_finite()).unwrap_or(f64::NAN);
            return Err(super::bytes::not_finite(what, i, bad));
        }
        out.push(v);
    }
    Ok(Some(out))
}

const UV_NAMES: [[&str; 2]; 4] = [["s", "t"], ["u", "v"], ["texture_u", "texture_v"], ["texture_s", "texture_t"]];
const VERTEX_PROPS: [&str; 6] = ["x", "y", "z", "nx", "ny", "nz"];

/// Reads a triangle mesh from PLY bytes (ASCII or binary).
pub fn read_ply_mesh_bytes(bytes: &[u8]) -> Result<TriMesh> {
    let data = read_ply(bytes, |el, p| match el {
        "vertex" => VERTEX_PROPS.contains(&p) || UV_NAMES.iter().any(|uv| uv.contains(&p)),
        "face" => p == "vertex_indices" || p == "vertex_index",
        _ => false,
    })?;
    let vert = data
        .element("vertex")
        .ok_or_else(|| FormatError::from(FormatErrorKind::Invalid("the PLY file has no `vertex` element".into())))?;
    let vertices = vec3s(vert, ["x", "y", "z"], "vertex")?.ok_or_else(|| {
        FormatError::from(FormatErrorKind::Invalid("the PLY `vertex` element lacks x, y or z".into()))
    })?;
    let normals = vec3s(vert, ["nx", "ny", "nz"], "vertex normal")?;
    let mut uvs = None;
    for [u, v] in UV_NAMES {
        if let (Some(u), Some(v)) = (vert.scalar(u), vert.scalar(v)) {
            let mut out = Vec::with_capacity(u.len());
            for i in 0..u.len() {
                let uv = Vec2::new(u[i] as f32, v[i] as f32);
                if !uv.is_finite() {
                    return Err(super::bytes::not_finite("vertex UV", i, if uv.x.is_finite() { v[i] } else { u[i] }));
                }
                out.push(uv);
            }
            uvs = Some(out);
            break;
        }
    }
    let mut triangles = Vec::new();
    if let Some(face) = data.element("face") {
        let (offsets, values) = face.list("vertex_indices").or_else(|| face.list("vertex_index")).ok_or_else(|| {
            FormatError::from(FormatErrorKind::Invalid(
                "the PLY `face` element has no `vertex_indices` or `vertex_index` list".into(),
            ))
        })?;
        triangles.reserve(values.len().saturating_sub(2 * face.count));
        for (f, w) in offsets.windows(2).enumerate() {
            let idx = &values[w[0]..w[1]];
            if idx.len() < 3 {
                return Err(FormatErrorKind::Invalid(format!(
                    "face {f} has {} corner(s); every face needs at least 3",
                    idx.len()
                ))
                .into());
            }
            let n = vertices.len();
            let a = to_index(idx[0], "face", f, n)?;
            let mut b = to_index(idx[1], "face", f, n)?;
            for &c in &idx[2..] {
                let c = to_index(c, "face", f, n)?;
                triangles.push([a, b, c]);
                b = c;
            }
        }
    }
    Ok(TriMesh::new(vertices, triangles, normals, uvs)?)
}

/// Writes a mesh as binary little-endian PLY.
pub fn write_ply_mesh<W: Write>(w: &mut W, mesh: &TriMesh) -> Result<()> {
    write_ply_mesh_with_quality(w, mesh, None)
}

/// Writes a mesh as binary little-endian PLY with a per-vertex scalar `quality` (the property
/// MeshLab and CloudCompare show as a colour ramp), one value per vertex.
pub fn write_ply_mesh_with_quality<W: Write>(w: &mut W, mesh: &TriMesh, quality: Option<&[f32]>) -> Result<()> {
    if let Some(q) = quality {
        if q.len() != mesh.vertices.len() {
            return Err(FormatErrorKind::CountMismatch {
                what: "per-vertex quality values",
                expected: mesh.vertices.len() as u64,
                found: q.len() as u64,
            }
            .into());
        }
    }
    let mut h = String::from("ply\nformat binary_little_endian 1.0\ncomment written by hairrecon\n");
    h += &format!("element vertex {}\nproperty float x\nproperty float y\nproperty float z\n", mesh.vertices.len());
    if mesh.normals.is_some() {
        h += "property float nx\nproperty float ny\nproperty float nz\n";
    }
    if mesh.uvs.is_some() {
        h += "property float s\nproperty float t\n";
    }
    if quality.is_some() {
        h += "property float quality\n";
    }
    h += &format!("element face {}\nproperty list uchar uint vertex_indices\nend_header\n", mesh.triangles.len());
    let per_vertex = 12
        + if mesh.normals.is_some() { 12 } else { 0 }
        + if mesh.uvs.is_some() { 8 } else { 0 }
        + if quality.is_some() { 4 } else { 0 };
    let mut buf = Vec::with_capacity(h.len() + mesh.vertices.len() * per_vertex + mesh.triangles.len() * 13);
    buf.extend_from_slice(h.as_bytes());
    for (i, v) in mesh.vertices.iter().enumerate() {
        let mut vals: Vec<f32> = v.to_array().to_vec();
        if let Some(n) = &mesh.normals {
            vals.extend(n[i].to_array());
        }
        if let Some(uv) = &mesh.uvs {
            vals.extend(uv[i].to_array());
        }
        if let Some(q) = quality {
            vals.push(q[i]);
        }
        for x in vals {
            buf.extend_from_slice(&x.to_le_bytes());
        }
    }
    for t in &mesh.triangles {
        buf.push(3);
        for &i in t {
            buf.extend_from_slice(&i.to_le_bytes());
        }
    }
    w.write_all(&buf)?;
    Ok(())
}

/// Writes a mesh as binary little-endian PLY into memory.
pub fn write_ply_mesh_bytes(mesh: &TriMesh) -> Vec<u8> {
    let mut out = Vec::new();
    // Writing to a Vec cannot fail.
    let _ = write_ply_mesh(&mut out, mesh);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad_ascii() -> &'static str {
        "ply\nformat ascii 1.0\ncomment a unit square and an extra element\nelement vertex 4\n\
         property double x\nproperty double y\nproperty double z\nproperty uchar red\n\
         property float u\nproperty float v\nelement face 1\nproperty list uchar int vertex_index\n\
         property float quality\nelement extra 2\nproperty list int float stuff\nend_header\n\
         0 0 0 255 0 0\n1 0 0 255 1 0\n1 1 0 255 1 1\n0 1 0 255 0 1\n4 0 1 2 3 0.5\n2 1.5 2.5\n0\n"
    }

    #[test]
    fn ascii_quad_is_fan_triangulated_and_extras_skipped() {
        let m = read_ply_mesh_bytes(quad_ascii().as_bytes()).unwrap();
        assert_eq!(m.vertices.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(m.uvs.as_ref().unwrap()[2], Vec2::new(1.0, 1.0));
        assert!(m.normals.is_none());
        assert_eq!(m.vertices[1], Vec3::X);
    }

    #[test]
    fn binary_round_trip_both_endians() {
        let m = read_ply_mesh_bytes(quad_ascii().as_bytes()).unwrap();
        let m = TriMesh::new(m.vertices.clone(), m.triangles.clone(), Some(m.compute_vertex_normals()), m.uvs).unwrap();
        let bytes = write_ply_mesh_bytes(&m);
        assert_eq!(read_ply_mesh_bytes(&bytes).unwrap(), m);
        // Big-endian with doubles and ushort indices, built by hand.
        let mut be = b"ply\r\nformat binary_big_endian 1.0\r\nelement vertex 3\r\nproperty double x\r\n\
            property double y\r\nproperty double z\r\nelement face 1\r\nproperty list ushort ushort vertex_indices\r\n\
            end_header\r\n"
            .to_vec();
        for v in [[0.0f64, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 3.0, 0.5]] {
            for c in v {
                be.extend_from_slice(&c.to_be_bytes());
            }
        }
        for i in [3u16, 2, 1, 0] {
            be.extend_from_slice(&i.to_be_bytes());
        }
        let m = read_ply_mesh_bytes(&be).unwrap();
        assert_eq!(m.triangles, vec![[2, 1, 0]]);
        assert_eq!(m.vertices[2], Vec3::new(0.0, 3.0, 0.5));
        // One trailing byte is an error, not ignored.
        be.push(0);
        let e = read_ply_mesh_bytes(&be).unwrap_err();
        assert!(matches!(e.kind, FormatErrorKind::TrailingBytes { count: 1, .. }), "{e}");
    }

    #[test]
    fn huge_counts_are_rejected_before_allocating() {
        let h = b"ply\nformat binary_little_endian 1.0\nelement vertex 18446744073709551615\nproperty float x\n\
                  property float y\nproperty float z\nend_header\n";
        let e = read_ply_mesh_bytes(h).unwrap_err();
        assert!(matches!(e.kind, FormatErrorKind::CountTooLarge { .. }), "{e}");
        let e = read_ply_mesh_bytes(b"plx\n").unwrap_err();
        assert!(matches!(e.kind, FormatErrorKind::BadMagic { .. }), "{e}");
    }

    #[test]
    fn bad_indices_and_nan_are_errors() {
        let s = quad_ascii().replace("4 0 1 2 3", "4 0 1 2 9");
        let e = read_ply_mesh_bytes(s.as_bytes()).unwrap_err();
        assert!(matches!(e.kind, FormatErrorKind::IndexOutOfRange { value: 9, .. }), "{e}");
        let s = quad_ascii().replace("1 1 0 255", "1 nan 0 255");
        let e = read_ply_mesh_bytes(s.as_bytes()).unwrap_err();
        assert!(matches!(e.kind, FormatErrorKind::NotFinite { index: 2, .. }), "{e}");
    }
}
