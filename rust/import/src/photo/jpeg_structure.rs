//! A structural completeness check of a JPEG file: its markers, read from the start of image (SOI)
//! to the end of image (EOI).
//!
//! The `image` crate's JPEG decoder (zune-jpeg in lenient mode) decodes a truncated file without
//! error and fills the missing rows with grey, so a photo cut short by an interrupted copy would
//! silently become a bad view. This walk finds that: a JPEG is a sequence of marker segments
//! (`FF xx`, most followed by a big-endian 16-bit length that counts itself), and after each start
//! of scan (SOS, `FF DA`) comes entropy-coded data in which a literal `FF` byte is stuffed as `FF 00`
//! and restart markers `FF D0`..`FF D7` may appear; the next other marker ends the scan. A complete
//! file reaches EOI (`FF D9`). Bytes after the first EOI (thumbnails, MPF secondary images, vendor
//! trailers) are not looked at.
//!
//! Reference: ITU-T Recommendation T.81 (1992) | ISO/IEC 10918-1, "Digital compression and coding
//! of continuous-tone still images", Annex B (compressed data formats).

/// `Ok` when `bytes` hold a JPEG whose marker structure reaches EOI; otherwise what is wrong.
pub(crate) fn check_complete(bytes: &[u8]) -> Result<(), String> {
    const SOI: u8 = 0xD8;
    const EOI: u8 = 0xD9;
    const SOS: u8 = 0xDA;
    let truncated = |at: usize| {
        Err(format!(
            "the JPEG data ends after {at} of {} bytes without an end-of-image marker (the file is truncated)",
            bytes.len()
        ))
    };
    if bytes.len() < 2 || bytes[0] != 0xFF || bytes[1] != SOI {
        return Err("the file does not start with a JPEG start-of-image marker".into());
    }
    let mut i = 2;
    loop {
        // a marker: one or more FF fill bytes, then its code
        if i >= bytes.len() {
            return truncated(bytes.len());
        }
        if bytes[i] != 0xFF {
            return Err(format!("byte {i}: expected a JPEG marker, found 0x{:02X} (the file is corrupt)", bytes[i]));
        }
        while i < bytes.len() && bytes[i] == 0xFF {
            i += 1;
        }
        let Some(&code) = bytes.get(i) else { return truncated(bytes.len()) };
        i += 1;
        match code {
            EOI => return Ok(()),
            0x01 | 0xD0..=0xD7 => continue, // no length field
            _ => {}
        }
        let (Some(&hi), Some(&lo)) = (bytes.get(i), bytes.get(i + 1)) else { return truncated(bytes.len()) };
        let len = usize::from(u16::from_be_bytes([hi, lo]));
        if len < 2 {
            return Err(format!("byte {i}: a JPEG segment length of {len} (the file is corrupt)"));
        }
        i += len;
        if i > bytes.len() {
            return truncated(bytes.len());
        }
        if code == SOS {
            // entropy-coded data up to the next marker other than a stuffed FF 00 or a restart
            loop {
                let Some(off) = bytes[i..].iter().position(|&b| b == 0xFF) else { return truncated(bytes.len()) };
                i += off;
                match bytes.get(i + 1) {
                    None => return truncated(bytes.len()),
                    Some(0x00) | Some(0xD0..=0xD7) | Some(0xFF) => i += 1,
                    Some(_) => break,
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn jpeg() -> Vec<u8> {
        let img =
            image::RgbImage::from_fn(64, 48, |x, y| image::Rgb([(x * 4) as u8, (y * 5) as u8, ((x ^ y) * 7) as u8]));
        let mut bytes = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 90).encode_image(&img).unwrap();
        bytes
    }

    #[test]
    fn a_whole_jpeg_passes_and_every_truncation_fails() {
        let bytes = jpeg();
        assert_eq!(check_complete(&bytes), Ok(()));
        let mut with_trailer = bytes.clone();
        with_trailer.extend_from_slice(b"vendor trailer \xFF\x12 after EOI");
        assert_eq!(check_complete(&with_trailer), Ok(()));
        for n in 0..bytes.len() {
            assert!(check_complete(&bytes[..n]).is_err(), "cut at {n} of {} passed", bytes.len());
        }
        assert!(check_complete(&bytes[..bytes.len() / 2]).unwrap_err().contains("truncated"));
    }

    #[test]
    fn not_a_jpeg_fails() {
        assert!(check_complete(b"\x89PNG\r\n\x1a\n").is_err());
        assert!(check_complete(b"\xFF\xD8\x00\x00").unwrap_err().contains("corrupt"));
    }
}
