//! Cem Yuksel's HAIR file format (`.hair`), the format of the hair models of the synthetic benchmark.
//!
//! Reference: Cem Yuksel, "HAIR Model Files", <http://www.cemyuksel.com/research/hairmodels/>.
//!
//! All values are little-endian. A 128-byte header:
//!
//! | bytes | field |
//! |---|---|
//! | 0..4 | signature `"HAIR"` |
//! | 4..8 | `u32` number of strands |
//! | 8..12 | `u32` total number of points |
//! | 12..16 | `u32` flags: bit 0 segments array, bit 1 points array, bit 2 thickness array, bit 3 transparency array, bit 4 colour array |
//! | 16..20 | `u32` default number of segments (used when there is no segments array) |
//! | 20..24 | `f32` default thickness |
//! | 24..28 | `f32` default transparency |
//! | 28..40 | `3 x f32` default colour |
//! | 40..128 | file information, text padded with zeros |
//!
//! then the arrays that the flags announce, in this order: segments (`u16` per strand; a strand has
//! segments + 1 points), points (`3 x f32` per point), thickness (`f32` per point), transparency
//! (`f32` per point), colour (`3 x f32` per point).
//!
//! The reader requires the points array, checks that the segment counts add up to the point count
//! and that the arrays fill the file exactly, and rejects non-finite values. A strand of 0 segments
//! (one point) is an error unless [`StrandReadOptions::skip_short_strands`] is set, in which case
//! it is dropped with its per-point values. The writer always writes the segments array and writes
//! thickness, transparency and colour when the [`HairFile`] has them.

use std::path::Path;

use glam::Vec3;

use super::bytes::{not_finite, Cursor, Endian};
use super::{read_file, FormatErrorKind, Result, StrandReadOptions};
use crate::strands::StrandSet;

/// Size of the header in bytes.
pub const HEADER_SIZE: usize = 128;
const SEGMENTS: u32 = 1;
const POINTS: u32 = 2;
const THICKNESS: u32 = 4;
const TRANSPARENCY: u32 = 8;
const COLOR: u32 = 16;

/// A `.hair` file: the strands and the optional per-point arrays, with the header's defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct HairFile {
    pub strands: StrandSet,
    /// Per-point thickness, if the file has it.
    pub thickness: Option<Vec<f32>>,
    /// Per-point transparency, if the file has it.
    pub transparency: Option<Vec<f32>>,
    /// Per-point RGB colour, if the file has it.
    pub color: Option<Vec<[f32; 3]>>,
    pub default_thickness: f32,
    pub default_transparency: f32,
    pub default_color: [f32; 3],
    /// The header's file information text (at most 88 bytes are written).
    pub info: String,
}

impl From<StrandSet> for HairFile {
    fn from(strands: StrandSet) -> Self {
        Self {
            strands,
            thickness: None,
            transparency: None,
            color: None,
            default_thickness: 1.0,
            default_transparency: 0.0,
            default_color: [0.0; 3],
            info: "written by hairrecon".into(),
        }
    }
}

/// Reads a `.hair` file; the error names the file.
pub fn read_hair(path: impl AsRef<Path>, options: StrandReadOptions) -> Result<HairFile> {
    let path = path.as_ref();
    let bytes = read_file(path)?;
    read_hair_bytes_with(&bytes, options).map(|(h, _)| h).map_err(|e| e.in_file(path))
}

/// Reads `.hair` bytes, rejecting one-point strands.
pub fn read_hair_bytes(bytes: &[u8]) -> Result<HairFile> {
    read_hair_bytes_with(bytes, StrandReadOptions::default()).map(|(h, _)| h)
}

/// Reads `.hair` bytes; returns the file and the number of one-point strands skipped.
pub fn read_hair_bytes_with(bytes: &[u8], options: StrandReadOptions) -> Result<(HairFile, usize)> {
    const LE: Endian = Endian::Little;
    let mut c = Cursor::new(bytes);
    let magic = c.take(4.min(bytes.len()), "the signature")?;
    if magic != b"HAIR" {
        let found = String::from_utf8_lossy(magic).into_owned();
        return Err(FormatErrorKind::BadMagic { format: "Cem Yuksel .hair", expected: "HAIR", found }.into());
    }
    let mut c = Cursor::new(bytes);
    c.take(HEADER_SIZE, "the 128-byte header")?;
    let mut h = Cursor::new(&bytes[4..HEADER_SIZE]);
    let num_strands = h.u32(LE, "strand count")? as u64;
    let num_points = h.u32(LE, "point count")? as u64;
    let flags = h.u32(LE, "flags")?;
    let default_segments = h.u32(LE, "default segments")? as u64;
    let default_thickness = h.f32(LE, "default thickness")?;
    let default_transparency = h.f32(LE, "default transparency")?;
    let default_color = [h.f32(LE, "default colour")?, h.f32(LE, "default colour")?, h.f32(LE, "default colour")?];
    let info_bytes = &bytes[40..HEADER_SIZE];
    let info_len = info_bytes.iter().position(|&b| b == 0).unwrap_or(info_bytes.len());
    let info = String::from_utf8_lossy(&info_bytes[..info_len]).into_owned();
    if flags & POINTS == 0 {
        return Err(FormatErrorKind::Header(
            "the flags say the file has no points array; hairrecon needs strand points".into(),
        )
        .into());
    }
    if flags & !31 != 0 {
        return Err(FormatErrorKind::Header(format!("unknown flag bits {flags:#x}; only bits 0-4 are defined")).into());
    }
    // Segments: one u16 per strand, or the default for all.
    let mut counts: Vec<u32> = Vec::new();
    if flags & SEGMENTS != 0 {
        let n = c.check_count(num_strands, 2, "strand segment counts")?;
        counts.reserve(n);
        for _ in 0..n {
            counts.push(c.u16(LE, "the segments array")? as u32 + 1);
        }
    } else {
        // Without an array every strand has the default: the total must match.
        let per = default_segments + 1;
        if num_strands.checked_mul(per) != Some(num_points) {
            return Err(FormatErrorKind::CountMismatch {
                what: "points (strand count x (default segments + 1))",
                expected: num_strands.saturating_mul(per),
                found: num_points,
            }
            .into());
        }
        let n = c.check_count(num_strands, 12 * per, "strands")?;
        counts = vec![per as u32; n];
    }
    let sum: u64 = counts.iter().map(|&k| k as u64).sum();
    if sum != num_points {
        return Err(FormatErrorKind::CountMismatch {
            what: "points (sum of segments + 1 over strands)",
            expected: sum,
            found: num_points,
        }
        .into());
    }
    // The per-point arrays must fill the rest of the file exactly.
    let per_point = 12
        + if flags & THICKNESS != 0 { 4 } else { 0 }
        + if flags & TRANSPARENCY != 0 { 4 } else { 0 }
        + if flags & COLOR != 0 { 12 } else { 0 };
    let np = c.check_count(num_points, per_point, "points")?;
    if c.remaining() as u64 > num_points * per_point {
        return Err(FormatErrorKind::TrailingBytes {
            what: "per-point array",
            count: c.remaining() as u64 - num_points * per_point,
        }
        .into());
    }
    let mut points = Vec::with_capacity(np);
    for i in 0..np {
        let p = Vec3::new(c.f32(LE, "points")?, c.f32(LE, "points")?, c.f32(LE, "points")?);
        if !p.is_finite() {
            let bad = p.to_array().into_iter().find(|v| !v.is_finite()).unwrap_or(f32::NAN);
            return Err(not_finite("point", i, bad as f64));
        }
        points.push(p);
    }
    let mut scalars = |on: bool, width: usize, what: &'static str| -> Result<Option<Vec<f32>>> {
        if !on {
            return Ok(None);
        }
        let mut v = Vec::with_capacity(np * width);
        for i in 0..np * width {
            let x = c.f32(LE, what)?;
            if !x.is_finite() {
                return Err(not_finite(what, i / width, x as f64));
            }
            v.push(x);
        }
        Ok(Some(v))
    };
    let mut thickness = scalars(flags & THICKNESS != 0, 1, "thickness")?;
    let mut transparency = scalars(flags & TRANSPARENCY != 0, 1, "transparency")?;
    let mut color: Option<Vec<[f32; 3]>> =
        scalars(flags & COLOR != 0, 3, "colour")?.map(|v| v.chunks_exact(3).map(|x| [x[0], x[1], x[2]]).collect());
    c.expect_end("per-point array")?;
    // Drop or reject one-point strands.
    let mut skipped = 0;
    if let Some(s) = counts.iter().position(|&k| k < 2) {
        if !options.skip_short_strands {
            return Err(FormatErrorKind::ShortStrand {
                strand: s as u64,
                count: counts[s] as u64,
                hint: "; or read with skip_short_strands",
            }
            .into());
        }
        let mut keep = Vec::with_capacity(np);
        for &k in &counts {
            keep.resize(keep.len() + k as usize, k >= 2);
        }
        let filter =
            |v: Vec<f32>| -> Vec<f32> { v.into_iter().zip(&keep).filter(|(_, &k)| k).map(|(x, _)| x).collect() };
        points = points.into_iter().zip(&keep).filter(|(_, &k)| k).map(|(p, _)| p).collect();
        thickness = thickness.map(filter);
        transparency = transparency.map(filter);
        color = color.map(|v| v.into_iter().zip(&keep).filter(|(_, &k)| k).map(|(x, _)| x).collect());
        skipped = counts.iter().filter(|&&k| k < 2).count();
        counts.retain(|&k| k >= 2);
    }
    let strands = StrandSet::new(points, counts)?;
    Ok((
        HairFile {
            strands,
            thickness,
            transparency,
            color,
            default_thickness,
            default_transparency,
            default_color,
            info,
        },
        skipped,
    ))
}

/// Writes a `.hair` file into memory. Fails if a strand has more than 65,536 points (the segments
/// array holds `u16`) or if a per-point array does not have one entry per point.
pub fn write_hair_bytes(hair: &HairFile) -> Result<Vec<u8>> {
    encode(&hair.strands, Some(hair))
}

/// Writes strands alone as a `.hair` file into memory (no per-point arrays, default header values).
pub fn write_hair_strands_bytes(strands: &StrandSet) -> Result<Vec<u8>> {
    encode(strands, None)
}

/// Encodes `s` with the per-point arrays and header values of `meta` (whose strands are ignored).
fn encode(s: &StrandSet, meta: Option<&HairFile>) -> Result<Vec<u8>> {
    let n = s.num_points();
    if let Some(i) = s.counts().iter().position(|&k| k > u16::MAX as u32 + 1) {
        return Err(FormatErrorKind::Invalid(format!(
            "strand {i} has {} points but a .hair file holds at most 65,536 per strand; resample it",
            s.counts()[i]
        ))
        .into());
    }
    if s.num_strands() > u32::MAX as usize || n > u32::MAX as usize {
        return Err(
            FormatErrorKind::Invalid("too many strands or points for a .hair file (2^32 - 1 at most)".into()).into()
        );
    }
    let defaults;
    let hair = match meta {
        Some(h) => h,
        None => {
            defaults = HairFile::from(StrandSet::empty());
            &defaults
        }
    };
    for (what, len) in [
        ("thickness", hair.thickness.as_ref().map(Vec::len)),
        ("transparency", hair.transparency.as_ref().map(Vec::len)),
        ("colour", hair.color.as_ref().map(Vec::len)),
    ] {
        if let Some(len) = len.filter(|&l| l != n) {
            return Err(FormatErrorKind::CountMismatch { what, expected: n as u64, found: len as u64 }.into());
        }
    }
    let mut flags = SEGMENTS | POINTS;
    flags |= if hair.thickness.is_some() { THICKNESS } else { 0 };
    flags |= if hair.transparency.is_some() { TRANSPARENCY } else { 0 };
    flags |= if hair.color.is_some() { COLOR } else { 0 };
    let mut out = Vec::with_capacity(HEADER_SIZE + 2 * s.num_strands() + 32 * n);
    out.extend_from_slice(b"HAIR");
    for v in [s.num_strands() as u32, n as u32, flags, 0] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in [hair.default_thickness, hair.default_transparency] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in hair.default_color {
        out.extend_from_slice(&v.to_le_bytes());
    }
    let mut info = [0u8; HEADER_SIZE - 40];
    let text = hair.info.as_bytes();
    let len = text.len().min(info.len());
    info[..len].copy_from_slice(&text[..len]);
    out.extend_from_slice(&info);
    for &k in s.counts() {
        out.extend_from_slice(&((k - 1) as u16).to_le_bytes());
    }
    for v in s.points().iter().flat_map(|p| p.to_array()) {
        out.extend_from_slice(&v.to_le_bytes());
    }
    let arrays = [hair.thickness.as_deref(), hair.transparency.as_deref()];
    for v in arrays.into_iter().flatten().flatten() {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in hair.color.iter().flatten().flatten() {
        out.extend_from_slice(&v.to_le_bytes());
    }
    Ok(out)
}

/// Writes a `.hair` file atomically.
pub fn write_hair(path: impl AsRef<Path>, hair: &HairFile) -> Result<()> {
    let path = path.as_ref();
    let bytes = write_hair_bytes(hair).map_err(|e| e.in_file(path))?;
    super::atomic_write(path, |w| Ok(std::io::Write::write_all(w, &bytes)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> HairFile {
        let pts: Vec<Vec3> = (0..7).map(|i| Vec3::new(i as f32, 0.5 * i as f32, -0.25)).collect();
        let mut h = HairFile::from(StrandSet::new(pts, vec![3, 4]).unwrap());
        h.thickness = Some((0..7).map(|i| 0.1 * i as f32).collect());
        h.color = Some((0..7).map(|i| [i as f32, 0.0, 1.0]).collect());
        h
    }

    #[test]
    fn layout_and_round_trip() {
        let h = sample();
        let b = write_hair_bytes(&h).unwrap();
        // Header, 2 u16 segment counts, 7 points, 7 thicknesses, 7 colours.
        assert_eq!(b.len(), 128 + 2 * 2 + 7 * 12 + 7 * 4 + 7 * 12);
        assert_eq!(&b[12..16], &(1u32 | 2 | 4 | 16).to_le_bytes());
        assert_eq!(&b[128..132], &[2, 0, 3, 0]);
        assert_eq!(read_hair_bytes(&b).unwrap(), h);
    }

    #[test]
    fn default_segments_and_short_strands() {
        // No segments array: 2 strands of default 2 segments = 6 points.
        let mut b = write_hair_bytes(&HairFile::from(
            StrandSet::new((0..6).map(|i| Vec3::splat(i as f32)).collect(), vec![3, 3]).unwrap(),
        ))
        .unwrap();
        b.drain(128..132);
        b[12..16].copy_from_slice(&2u32.to_le_bytes());
        b[16..20].copy_from_slice(&2u32.to_le_bytes());
        let h = read_hair_bytes(&b).unwrap();
        assert_eq!(h.strands.counts(), &[3, 3]);
        // A strand of 0 segments: an error, or dropped on request with its per-point values.
        let mut b = write_hair_bytes(&sample()).unwrap();
        b[128..130].copy_from_slice(&0u16.to_le_bytes());
        b[130..132].copy_from_slice(&5u16.to_le_bytes());
        let e = read_hair_bytes(&b).unwrap_err();
        assert!(matches!(e.kind, FormatErrorKind::ShortStrand { strand: 0, count: 1, .. }), "{e}");
        let (h, skipped) = read_hair_bytes_with(&b, StrandReadOptions { skip_short_strands: true }).unwrap();
        assert_eq!((skipped, h.strands.counts()), (1, &[6u32][..]));
        assert_eq!(h.strands.strand(0)[0], Vec3::new(1.0, 0.5, -0.25));
        assert_eq!(h.thickness.unwrap().len(), 6);
        assert_eq!(h.color.unwrap()[0], [1.0, 0.0, 1.0]);
    }
}
