//! Photos of a capture: loading (JPEG, PNG, TIFF; 8- or 16-bit), the EXIF orientation, choosing the
//! orientation a calibration was made on, and resampling to the working copy ([`resample`]).
//!
//! **Pixels as stored.** [`load_photo`] keeps the samples the file stores, in the file's own colour
//! encoding (normally sRGB; nothing is linearized), as 8-bit or 16-bit RGB: gray is repeated into
//! three channels and alpha is dropped. 8-bit photos stay `u8` until [`resample`] reads them, so a
//! 24-megapixel JPEG takes 72 MB. 32-bit float TIFFs are refused (photos are not HDR data).
//!
//! **EXIF orientation.** Cameras store the sensor's rows as read out and record how to display
//! them in the EXIF Orientation tag (0x0112; values 1 to 8, CIPA DC-008 "Exchangeable image file
//! format for digital still cameras: Exif", table of Orientation). 6 means "rotate 90° clockwise to
//! display", 8 "rotate 90° counter-clockwise", 3 "rotate 180°", 2/4/5/7 add a mirror. The tag is read
//! from JPEG APP1, PNG eXIf and TIFF IFD0 (the `image` crate's `ImageDecoder::orientation`); a
//! missing or out-of-range tag counts as 1.
//!
//! **Which orientation the calibration used.** A calibration is made on the pixels its tool read,
//! and its camera's width and height say which: [`Photo::oriented_to`] gives the stored pixels when
//! their size matches the camera, else the EXIF-oriented ones when theirs does, else an error. When
//! both match (orientations 1 to 4, or a square photo) it prefers the stored pixels, because that is
//! what structure-from-motion tools usually calibrate: COLMAP reads pixels as stored and ignores the
//! tag so that portrait and landscape shots of one camera share intrinsics (auto-rotation added in
//! colmap/colmap PR #1318 was reverted in PR #1406, January 2022; the maintainers confirm the tag
//! is intentionally not applied in issue #2104, 2023; PR #4122, 2026, reads the tag to extract
//! upright features). A tool that applied the tag can be followed with
//! [`Photo::oriented_to_preferring`] and [`Prefer::Exif`].

mod jpeg_structure;
mod resample;

use std::borrow::Cow;
use std::io::Cursor;
use std::path::{Path, PathBuf};

use image::{DynamicImage, ImageBuffer, ImageDecoder, ImageFormat, ImageReader, Rgb};
use thiserror::Error;

pub use image::metadata::Orientation;
pub use resample::{resample, scaled_intrinsics, working_size, Resampled};

/// 16-bit RGB pixels.
pub type Rgb16Image = ImageBuffer<Rgb<u16>, Vec<u16>>;

/// Why a photo could not be loaded, oriented or resampled.
#[derive(Debug, Error)]
pub enum PhotoError {
    #[error(
        "photo {path} does not exist; check the images folder given to the importer and that the \
         calibration names its photos as they are on disk"
    )]
    Missing { path: PathBuf },
    #[error("cannot read photo {path}: {source}; check that the file is readable")]
    Io { path: PathBuf, source: std::io::Error },
    #[error(
        "photo {path} cannot be decoded: {msg}; the file is truncated or corrupt: copy it again from \
         the camera or the original export"
    )]
    Unreadable { path: PathBuf, msg: String },
    #[error(
        "photo {path} is {what}; photos must be JPEG, PNG or TIFF with 8- or 16-bit samples: \
         convert it (for example to a 16-bit PNG or TIFF)"
    )]
    Unsupported { path: PathBuf, what: String },
    #[error(
        "photo {path} is {width}x{height} pixels as stored ({oriented_width}x{oriented_height} with \
         its EXIF orientation {exif} applied) but its camera says {camera_width}x{camera_height}; use \
         the photo the calibration was made from (not a resized, cropped or re-exported copy; an editor \
         that rotated the pixels may have dropped the EXIF orientation), or calibrate again with this one"
    )]
    SizeMismatch {
        path: PathBuf,
        width: u32,
        height: u32,
        exif: u8,
        oriented_width: u32,
        oriented_height: u32,
        camera_width: u32,
        camera_height: u32,
    },
    #[error(
        "photo {path} is {width}x{height} pixels ({megapixels} megapixels), more than the {} megapixels \
         hairrecon reads; scale it down (hairrecon works at a few hundred to a few thousand pixels of \
         height), or check that the file is what the camera wrote",
        MAX_PHOTO_PIXELS / 1_000_000
    )]
    TooLarge { path: PathBuf, width: u32, height: u32, megapixels: u64 },
    #[error("cannot resample a photo to a working height of {target_height} pixels; give a height of at least 1")]
    BadTarget { target_height: u32 },
    #[error("cannot resample a photo with intrinsics {intrinsics}; the calibration is invalid: check the camera")]
    BadIntrinsics { intrinsics: String },
}

/// The most pixels a photo may have (64 megapixels, above the largest full-frame cameras; 384 MB of
/// 16-bit RGB), checked from the header before decoding, so that a file claiming more (a corrupt
/// or malicious header) is refused without allocating it.
pub const MAX_PHOTO_PIXELS: u64 = 64_000_000;

/// A photo's pixels: 8-bit or 16-bit RGB, row-major.
#[derive(Debug, Clone, PartialEq)]
pub enum PhotoPixels {
    Rgb8(image::RgbImage),
    Rgb16(Rgb16Image),
}

impl PhotoPixels {
    pub fn width(&self) -> u32 {
        match self {
            Self::Rgb8(i) => i.width(),
            Self::Rgb16(i) => i.width(),
        }
    }

    pub fn height(&self) -> u32 {
        match self {
            Self::Rgb8(i) => i.height(),
            Self::Rgb16(i) => i.height(),
        }
    }

    /// Bits per sample: 8 or 16.
    pub fn bits(&self) -> u32 {
        match self {
            Self::Rgb8(_) => 8,
            Self::Rgb16(_) => 16,
        }
    }

    /// A copy with `orientation` applied (as a viewer displays the photo).
    pub fn oriented(&self, orientation: Orientation) -> PhotoPixels {
        match self {
            Self::Rgb8(i) => Self::Rgb8(apply_orientation(i, orientation)),
            Self::Rgb16(i) => Self::Rgb16(apply_orientation(i, orientation)),
        }
    }
}

fn apply_orientation<P: image::Pixel + 'static>(
    img: &ImageBuffer<P, Vec<P::Subpixel>>,
    orientation: Orientation,
) -> ImageBuffer<P, Vec<P::Subpixel>> {
    use image::imageops::{flip_horizontal_in_place, flip_vertical_in_place, rotate180_in_place, rotate270, rotate90};
    match orientation {
        Orientation::NoTransforms => img.clone(),
        Orientation::Rotate90 => rotate90(img),
        Orientation::Rotate270 => rotate270(img),
        Orientation::Rotate180 => {
            let mut out = img.clone();
            rotate180_in_place(&mut out);
            out
        }
        Orientation::FlipHorizontal => {
            let mut out = img.clone();
            flip_horizontal_in_place(&mut out);
            out
        }
        Orientation::FlipVertical => {
            let mut out = img.clone();
            flip_vertical_in_place(&mut out);
            out
        }
        Orientation::Rotate90FlipH => {
            let mut out = rotate90(img);
            flip_horizontal_in_place(&mut out);
            out
        }
        Orientation::Rotate270FlipH => {
            let mut out = rotate270(img);
            flip_horizontal_in_place(&mut out);
            out
        }
    }
}

/// True when `orientation` swaps width and height.
fn swaps_axes(orientation: Orientation) -> bool {
    matches!(
        orientation,
        Orientation::Rotate90 | Orientation::Rotate270 | Orientation::Rotate90FlipH | Orientation::Rotate270FlipH
    )
}

/// Which orientation [`Photo::oriented_to_preferring`] takes when both match the camera's size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Prefer {
    /// The pixels as stored (COLMAP's reading; the module docs).
    Stored,
    /// The pixels with the EXIF orientation applied.
    Exif,
}

/// A loaded photo: its pixels as stored and its EXIF orientation.
#[derive(Debug, Clone, PartialEq)]
pub struct Photo {
    pub path: PathBuf,
    /// The pixels in the file's row order, without the orientation applied.
    pub pixels: PhotoPixels,
    pub orientation: Orientation,
}

impl Photo {
    /// Width of the pixels as stored.
    pub fn width(&self) -> u32 {
        self.pixels.width()
    }

    /// Height of the pixels as stored.
    pub fn height(&self) -> u32 {
        self.pixels.height()
    }

    /// The EXIF orientation value, 1 to 8.
    pub fn exif_orientation(&self) -> u8 {
        self.orientation.to_exif()
    }

    /// Width and height with the orientation applied.
    pub fn oriented_size(&self) -> (u32, u32) {
        if swaps_axes(self.orientation) {
            (self.height(), self.width())
        } else {
            (self.width(), self.height())
        }
    }

    /// The pixels with the EXIF orientation applied (a copy).
    pub fn oriented(&self) -> PhotoPixels {
        self.pixels.oriented(self.orientation)
    }

    /// The pixels in the orientation a calibration of `width` x `height` was made on, preferring
    /// the stored pixels when both fit (module docs). Borrowed when they are the stored pixels.
    pub fn oriented_to(&self, width: u32, height: u32) -> Result<Cow<'_, PhotoPixels>, PhotoError> {
        self.oriented_to_preferring(width, height, Prefer::Stored)
    }

    /// [`Self::oriented_to`] with the choice when both orientations fit the camera's size.
    pub fn oriented_to_preferring(
        &self,
        width: u32,
        height: u32,
        prefer: Prefer,
    ) -> Result<Cow<'_, PhotoPixels>, PhotoError> {
        let stored = (self.width(), self.height()) == (width, height);
        let exif = self.oriented_size() == (width, height);
        let identity = self.orientation == Orientation::NoTransforms;
        match (stored, exif) {
            (true, true) if prefer == Prefer::Exif && !identity => Ok(Cow::Owned(self.oriented())),
            (true, _) => Ok(Cow::Borrowed(&self.pixels)),
            (false, true) => Ok(Cow::Owned(self.oriented())),
            (false, false) => {
                let (oriented_width, oriented_height) = self.oriented_size();
                Err(PhotoError::SizeMismatch {
                    path: self.path.clone(),
                    width: self.width(),
                    height: self.height(),
                    exif: self.exif_orientation(),
                    oriented_width,
                    oriented_height,
                    camera_width: width,
                    camera_height: height,
                })
            }
        }
    }
}

/// How decoding failed: the file is broken, or it is valid but not something this reads.
enum DecodeFailure {
    Broken(String),
    Unsupported(String),
    TooLarge(u32, u32),
}

impl From<image::ImageError> for DecodeFailure {
    fn from(e: image::ImageError) -> Self {
        match e {
            image::ImageError::Limits(l) => Self::Unsupported(format!("too large to decode ({l})")),
            image::ImageError::Unsupported(u) => {
                Self::Unsupported(format!("a variant the decoder does not support ({u})"))
            }
            other => Self::Broken(other.to_string()),
        }
    }
}

/// Runs a third-party decoder, turning a panic into an error.
fn guarded<T>(f: impl FnOnce() -> Result<T, DecodeFailure>) -> Result<T, DecodeFailure> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f))
        .unwrap_or_else(|_| Err(DecodeFailure::Broken("the decoder failed on malformed data".to_string())))
}

/// Loads a JPEG, PNG or TIFF photo (the type from the file's first bytes, not its name) with its
/// EXIF orientation; the module docs give the pixel format. A JPEG is first checked to be complete
/// (its markers are walked from start to end of image), since the decoder accepts truncated ones.
pub fn load_photo(path: impl AsRef<Path>) -> Result<Photo, PhotoError> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|source| match source.kind() {
        std::io::ErrorKind::NotFound => PhotoError::Missing { path: path.to_path_buf() },
        _ => PhotoError::Io { path: path.to_path_buf(), source },
    })?;
    let unsupported = |what: String| PhotoError::Unsupported { path: path.to_path_buf(), what };
    let unreadable = |msg: String| PhotoError::Unreadable { path: path.to_path_buf(), msg };
    let format = match image::guess_format(&bytes) {
        Ok(f @ (ImageFormat::Jpeg | ImageFormat::Png | ImageFormat::Tiff)) => f,
        Ok(other) => return Err(unsupported(format!("a {} file", other.extensions_str().first().unwrap_or(&"?")))),
        Err(_) => {
            let head: String = bytes.iter().take(8).map(|b| format!("{b:02X}")).collect::<Vec<_>>().join(" ");
            return Err(unsupported(format!("not a JPEG, PNG or TIFF file (its first bytes are {head})")));
        }
    };
    if format == ImageFormat::Jpeg {
        jpeg_structure::check_complete(&bytes).map_err(unreadable)?;
    }
    let (image, orientation) = guarded(|| {
        let mut decoder = ImageReader::with_format(Cursor::new(&bytes[..]), format).into_decoder()?;
        let (width, height) = decoder.dimensions();
        if width as u64 * height as u64 > MAX_PHOTO_PIXELS {
            return Err(DecodeFailure::TooLarge(width, height));
        }
        let orientation = decoder.orientation()?;
        let image = DynamicImage::from_decoder(decoder)?;
        Ok((image, orientation))
    })
    .map_err(|e| match e {
        DecodeFailure::Broken(msg) => unreadable(msg),
        DecodeFailure::Unsupported(what) => unsupported(what),
        DecodeFailure::TooLarge(width, height) => PhotoError::TooLarge {
            path: path.to_path_buf(),
            width,
            height,
            megapixels: (width as u64 * height as u64).div_ceil(1_000_000),
        },
    })?;
    drop(bytes);
    let pixels = match image {
        DynamicImage::ImageRgb8(i) => PhotoPixels::Rgb8(i),
        DynamicImage::ImageRgb16(i) => PhotoPixels::Rgb16(i),
        i @ (DynamicImage::ImageLuma8(_) | DynamicImage::ImageLumaA8(_) | DynamicImage::ImageRgba8(_)) => {
            PhotoPixels::Rgb8(i.to_rgb8())
        }
        i @ (DynamicImage::ImageLuma16(_) | DynamicImage::ImageLumaA16(_) | DynamicImage::ImageRgba16(_)) => {
            PhotoPixels::Rgb16(i.to_rgb16())
        }
        other => return Err(unsupported(format!("an image with {:?} samples", other.color()))),
    };
    Ok(Photo { path: path.to_path_buf(), pixels, orientation })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn photo(w: u32, h: u32, orientation: Orientation) -> Photo {
        let img = image::RgbImage::from_fn(w, h, |x, y| Rgb([x as u8, y as u8, 0]));
        Photo { path: "p.jpg".into(), pixels: PhotoPixels::Rgb8(img), orientation }
    }

    #[test]
    fn oriented_to_picks_by_size_and_prefers_stored_pixels() {
        let p = photo(6, 4, Orientation::Rotate90);
        assert_eq!(p.oriented_size(), (4, 6));
        assert!(matches!(p.oriented_to(6, 4).unwrap(), Cow::Borrowed(_)));
        let rotated = p.oriented_to(4, 6).unwrap();
        assert_eq!((rotated.width(), rotated.height()), (4, 6));
        let err = p.oriented_to(5, 4).unwrap_err().to_string();
        assert!(err.contains("p.jpg is 6x4 pixels as stored (4x6 with its EXIF orientation 6 applied)"), "{err}");
        assert!(err.contains("its camera says 5x4"), "{err}");
        // a 180° rotation keeps the size: stored by default, rotated when asked
        let p = photo(6, 4, Orientation::Rotate180);
        let PhotoPixels::Rgb8(stored) = p.oriented_to(6, 4).unwrap().into_owned() else { panic!() };
        assert_eq!(stored.get_pixel(0, 0).0, [0, 0, 0]);
        let PhotoPixels::Rgb8(turned) = p.oriented_to_preferring(6, 4, Prefer::Exif).unwrap().into_owned() else {
            panic!()
        };
        assert_eq!(turned.get_pixel(0, 0).0, [5, 3, 0]);
    }

    #[test]
    fn every_orientation_displays_the_stored_top_left_where_exif_says() {
        // where the stored (0, 0) lands on a W x H = 6 x 4 photo, displayed (CIPA DC-008)
        let cases = [
            (1, (0, 0)),
            (2, (5, 0)), // mirrored left-right: top-right
            (3, (5, 3)), // 180°: bottom-right
            (4, (0, 3)), // mirrored top-bottom: bottom-left
            (5, (0, 0)), // transposed: stays top-left of the 4 x 6 display
            (6, (3, 0)), // 90° clockwise: top-right
            (7, (3, 5)), // transverse: bottom-right
            (8, (0, 5)), // 90° counter-clockwise: bottom-left
        ];
        for (exif, (x, y)) in cases {
            let p = photo(6, 4, Orientation::from_exif(exif).unwrap());
            let PhotoPixels::Rgb8(img) = p.oriented() else { panic!() };
            assert_eq!(img.get_pixel(x, y).0, [0, 0, 0], "orientation {exif}");
            assert_eq!((img.width(), img.height()), p.oriented_size(), "orientation {exif}");
        }
    }
}
