//! USC-HairSalon strand files (`.data`).
//!
//! Reference: Liwen Hu, Chongyang Ma, Linjie Luo, Hao Li, "Single-View Hair Modeling Using a
//! Hairstyle Database", SIGGRAPH 2015; the dataset's format as documented with it
//! (<http://www-scf.usc.edu/~liwenhu/SHM/database.html>): little-endian
//! `i32 strand_count`, then for each strand `i32 point_count` and `point_count x (3 x f32)`.
//!
//! The dataset stores one strand per scalp sample, and samples where no hair grows have a single
//! point. A [`StrandSet`] needs at least two points per strand, so by default such a strand is an
//! error ([`FormatErrorKind::ShortStrand`]); with [`StrandReadOptions::skip_short_strands`] they are
//! dropped (strands of zero points too) and their number is returned. Negative counts, counts that
//! do not fit in the file, trailing bytes and non-finite coordinates are errors.

use std::path::Path;

use glam::Vec3;

use super::bytes::{not_finite, Cursor, Endian};
use super::{read_file, FormatErrorKind, Result, StrandReadOptions};
use crate::strands::StrandSet;

/// The options of the USC reader (the same as every strand reader's).
pub type UscReadOptions = StrandReadOptions;

const HINT: &str = "; USC-HairSalon marks scalp samples without hair by one-point strands: read with \
                    skip_short_strands (formats::read_strands_with) to drop them";

/// Reads a `.data` file; returns the strands and the number of strands skipped.
pub fn read_usc(path: impl AsRef<Path>, options: UscReadOptions) -> Result<(StrandSet, usize)> {
    let path = path.as_ref();
    let bytes = read_file(path)?;
    read_usc_bytes(&bytes, options).map_err(|e| e.in_file(path))
}

/// Reads `.data` bytes; returns the strands and the number of strands skipped.
pub fn read_usc_bytes(bytes: &[u8], options: UscReadOptions) -> Result<(StrandSet, usize)> {
    const LE: Endian = Endian::Little;
    let mut c = Cursor::new(bytes);
    let n = c.i32(LE, "the strand count")?;
    if n < 0 {
        return Err(
            FormatErrorKind::Header(format!("the strand count is negative ({n}); this is not a .data file")).into()
        );
    }
    let n = c.check_count(n as u64, 4, "strands")?;
    let mut counts = Vec::with_capacity(n);
    let mut points = Vec::with_capacity(c.remaining() / 12);
    let mut skipped = 0;
    for s in 0..n {
        let k = c.i32(LE, "a strand's point count")?;
        if k < 0 {
            return Err(FormatErrorKind::Invalid(format!("strand {s} has a negative point count ({k})")).into());
        }
        let k = c.check_count(k as u64, 12, "strand points")?;
        let keep = k >= 2;
        if !keep && !options.skip_short_strands {
            return Err(FormatErrorKind::ShortStrand { strand: s as u64, count: k as u64, hint: HINT }.into());
        }
        for _ in 0..k {
            let p = Vec3::new(c.f32(LE, "points")?, c.f32(LE, "points")?, c.f32(LE, "points")?);
            if !p.is_finite() {
                let bad = p.to_array().into_iter().find(|v| !v.is_finite()).unwrap_or(f32::NAN);
                return Err(not_finite("point", points.len(), bad as f64));
            }
            if keep {
                points.push(p);
            }
        }
        if keep {
            counts.push(k as u32);
        } else {
            skipped += 1;
        }
    }
    c.expect_end("strand")?;
    Ok((StrandSet::new(points, counts)?, skipped))
}

/// Writes strands as `.data` bytes.
pub fn write_usc_bytes(strands: &StrandSet) -> Vec<u8> {
    let mut out = Vec::with_capacity(4 + 4 * strands.num_strands() + 12 * strands.num_points());
    out.extend_from_slice(&(strands.num_strands() as i32).to_le_bytes());
    for s in strands.iter() {
        out.extend_from_slice(&(s.len() as i32).to_le_bytes());
        for p in s {
            for v in p.to_array() {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_round_trip_and_short_strands() {
        let s = StrandSet::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE], vec![2, 3]).unwrap();
        let b = write_usc_bytes(&s);
        assert_eq!(b.len(), 4 + 2 * 4 + 5 * 12);
        assert_eq!(&b[..8], &[2, 0, 0, 0, 2, 0, 0, 0]);
        assert_eq!(read_usc_bytes(&b, UscReadOptions::default()).unwrap(), (s.clone(), 0));
        // Prepend a one-point strand.
        let mut b2 = 3i32.to_le_bytes().to_vec();
        b2.extend_from_slice(&1i32.to_le_bytes());
        b2.extend_from_slice(&[0; 12]);
        b2.extend_from_slice(&b[4..]);
        let e = read_usc_bytes(&b2, UscReadOptions::default()).unwrap_err();
        assert!(matches!(e.kind, FormatErrorKind::ShortStrand { strand: 0, count: 1, .. }), "{e}");
        assert!(e.to_string().contains("skip_short_strands"), "{e}");
        let (r, skipped) = read_usc_bytes(&b2, UscReadOptions { skip_short_strands: true }).unwrap();
        assert_eq!((r, skipped), (s, 1));
    }
}
