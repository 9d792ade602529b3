//! Image I/O: PNG (8/16-bit) and OpenEXR float images as row-major `f32` buffers.
//!
//! References: PNG, W3C Recommendation "Portable Network Graphics (PNG) Specification (Third
//! Edition)" (<https://www.w3.org/TR/png-3/>), decoded and encoded with the `image` crate; OpenEXR,
//! "OpenEXR File Layout" (<https://openexr.com/en/latest/OpenEXRFileLayout.html>), read and written
//! with the `exr` crate (which, unlike `image`'s EXR codec, reads files without R, G and B channels).
//!
//! The file type is taken from the file's first bytes, not its name. Values:
//! - PNG: 8-bit samples are divided by 255 and 16-bit samples by 65,535, so they lie in `[0, 1]`.
//!   [`read_gray_f32`] of a colour PNG gives Rec. 709 luminance; alpha is dropped.
//! - EXR (first layer, largest resolution, half/float/uint samples as `f32`, unchanged): EXRs hold
//!   data (depth, orientation) more often than pictures, so [`read_gray_f32`] takes a channel, never
//!   a mix: the only channel of a one-channel file, else `Y` (luminance), else `R`.
//!   [`read_rgb_f32`] takes `R`, `G`, `B`, or repeats the gray channel of a gray file.
//!
//! Writers quantise to PNG with rounding after clamping to `[0, 1]`, write EXR as 32-bit float with
//! lossless ZIP compression (channel `Y` for gray, `R G B` for colour), and go through
//! [`crate::formats::atomic_write`]. Every error names the file and says what is wrong.
//!
//! Images as stored, without conversion to float (the Python module's `read_image` and
//! `write_image`): [`read_image`] gives a [`RawImage`] with the file's own samples (PNG: 8- or 16-bit
//! integers, 1 to 4 channels, palettes and bit depths under 8 expanded; EXR: `f32`, the channels
//! `R G B [A]`, `Y [A]` or the only one), [`write_image`] writes one (PNG or EXR by the extension),
//! and [`read_exr_channels`] / [`write_exr_channels`] give every named channel of an OpenEXR file, over
//! all its layers (Blender's multilayer render output).

use std::io::Cursor as IoCursor;
use std::path::Path;

use crate::formats::{atomic_write, read_file, FormatError, FormatErrorKind, Result};

/// A one-channel float image, row-major (`data[y * width + x]`).
#[derive(Debug, Clone, PartialEq)]
pub struct GrayImage32 {
    pub width: u32,
    pub height: u32,
    pub data: Vec<f32>,
}

/// A three-channel float image, row-major and interleaved (`data[3 * (y * width + x) + c]`).
#[derive(Debug, Clone, PartialEq)]
pub struct RgbImage32 {
    pub width: u32,
    pub height: u32,
    pub data: Vec<f32>,
}

fn invalid(msg: String) -> FormatError {
    FormatErrorKind::Invalid(msg).into()
}

fn check_size(width: u32, height: u32, channels: usize, len: usize) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(invalid(format!("an image must be at least 1x1 pixels, got {width}x{height}")));
    }
    let expected = width as u64 * height as u64 * channels as u64;
    if expected != len as u64 {
        return Err(invalid(format!(
            "a {width}x{height} image with {channels} channel(s) needs {expected} values but {len} were given"
        )));
    }
    Ok(())
}

impl GrayImage32 {
    /// Builds an image, checking that `data` has `width * height` values.
    pub fn new(width: u32, height: u32, data: Vec<f32>) -> Result<Self> {
        check_size(width, height, 1, data.len())?;
        Ok(Self { width, height, data })
    }

    /// An image filled with `value`.
    pub fn filled(width: u32, height: u32, value: f32) -> Self {
        Self { width, height, data: vec![value; width as usize * height as usize] }
    }

    /// The value at pixel `(x, y)`.
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> f32 {
        self.data[y as usize * self.width as usize + x as usize]
    }
}

impl RgbImage32 {
    /// Builds an image, checking that `data` has `3 * width * height` values.
    pub fn new(width: u32, height: u32, data: Vec<f32>) -> Result<Self> {
        check_size(width, height, 3, data.len())?;
        Ok(Self { width, height, data })
    }

    /// The colour at pixel `(x, y)`.
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }
}

const PNG_MAGIC: &[u8] = b"\x89PNG\r\n\x1a\n";
const EXR_MAGIC: &[u8] = &[0x76, 0x2f, 0x31, 0x01];

enum Decoded {
    Png(image::DynamicImage),
    /// Width, height and the named channels of the first layer.
    Exr(u32, u32, Vec<(String, Vec<f32>)>),
}

fn image_err(msg: impl std::fmt::Display) -> FormatError {
    FormatErrorKind::Image(msg.to_string()).into()
}

/// Runs a third-party decoder, turning a panic into an error.
fn guarded<T>(f: impl FnOnce() -> Result<T>) -> Result<T> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f))
        .unwrap_or_else(|_| Err(image_err("the decoder failed on malformed data; the file is corrupt")))
}

/// The most pixels an image read by this module may have (40 megapixels: 480 MB as float RGB),
/// checked from the header before decoding. Capture images are working copies (`hairrecon
/// import` scales photos down); a header claiming more is a mistake or a malicious file.
pub const MAX_PIXELS: u64 = 40_000_000;

fn check_pixels(width: u64, height: u64) -> Result<()> {
    if width.saturating_mul(height) > MAX_PIXELS {
        return Err(image_err(format!(
            "the image is {width}x{height} pixels, more than the {MAX_PIXELS} this reads; scale it down \
             (hairrecon import makes working copies of photos)"
        )));
    }
    Ok(())
}

/// The most a PNG's pixel data can expand from its file: deflate's limit (1032:1) and a margin.
const PNG_MAX_EXPANSION: u64 = 1100;
/// The same for OpenEXR, whose DWA compression stores one value per 8 × 8 block and deflates
/// those: about 64 × 1032 at most, with a margin.
const EXR_MAX_EXPANSION: u64 = 100_000;

/// A header that declares more pixel data than its file could hold under any compression is a
/// truncated or forged file: refused before the decoder allocates the image.
fn check_expansion(format: &str, file_len: usize, raw_bytes: u64, max_ratio: u64) -> Result<()> {
    if raw_bytes > (file_len as u64).saturating_mul(max_ratio) {
        return Err(image_err(format!(
            "the {format} header declares {raw_bytes} bytes of pixels, more than a file of {file_len} bytes can \
             hold; the file is truncated or corrupt"
        )));
    }
    Ok(())
}

/// Checks a PNG's header against [`MAX_PIXELS`] and its file size, before decoding.
fn check_png_header(bytes: &[u8]) -> Result<()> {
    use image::ImageDecoder;
    let decoder = image::codecs::png::PngDecoder::new(IoCursor::new(bytes)).map_err(image_err)?;
    let (w, h) = decoder.dimensions();
    check_pixels(w as u64, h as u64)?;
    check_expansion("PNG", bytes.len(), decoder.total_bytes(), PNG_MAX_EXPANSION)
}

fn decode(bytes: &[u8]) -> Result<Decoded> {
    if bytes.starts_with(PNG_MAGIC) {
        guarded(|| check_png_header(bytes))?;
        guarded(|| {
            let img = image::load_from_memory_with_format(bytes, image::ImageFormat::Png).map_err(image_err)?;
            Ok(Decoded::Png(img))
        })
    } else if bytes.starts_with(EXR_MAGIC) {
        guarded(|| decode_exr(bytes))
    } else {
        let found = String::from_utf8_lossy(&bytes[..bytes.len().min(8)]).into_owned();
        Err(FormatErrorKind::BadMagic { format: "PNG or OpenEXR", expected: "\\x89PNG or v/1\\x01", found }.into())
    }
}

/// The most float samples an OpenEXR file read by this module may hold over all its layers and
/// channels (48 million: 16 megapixels of RGB, or a 2048 × 2048 render with 11 channels), checked
/// from the header. Decoding holds about four copies of them (the decoder's, the channels', the
/// interleaved image and a conversion): 0.8 GB at most.
pub const MAX_EXR_SAMPLES: u64 = 48_000_000;

/// Checks an OpenEXR file's header against [`MAX_PIXELS`] per layer and [`MAX_EXR_SAMPLES`] in all,
/// before the decoder allocates what the header claims.
fn check_exr_header(bytes: &[u8]) -> Result<()> {
    let meta = guarded(|| {
        exr::meta::MetaData::read_from_buffered(IoCursor::new(bytes), false)
            .map_err(|e| image_err(format!("cannot read the OpenEXR header: {e}")))
    })?;
    let (mut samples, mut raw_bytes) = (0u64, 0u64);
    for h in &meta.headers {
        let (w, hh) = (h.layer_size.width() as u64, h.layer_size.height() as u64);
        check_pixels(w, hh)?;
        for c in &h.channels.list {
            samples = samples.saturating_add(w.saturating_mul(hh));
            raw_bytes =
                raw_bytes.saturating_add(w.saturating_mul(hh).saturating_mul(c.sample_type.bytes_per_sample() as u64));
        }
    }
    check_expansion("OpenEXR", bytes.len(), raw_bytes, EXR_MAX_EXPANSION)?;
    if samples > MAX_EXR_SAMPLES {
        return Err(image_err(format!(
            "the OpenEXR file holds {samples} samples over its layers and channels, more than the \
             {MAX_EXR_SAMPLES} this reads; write fewer or smaller layers"
        )));
    }
    Ok(())
}

fn decode_exr(bytes: &[u8]) -> Result<Decoded> {
    use exr::prelude::{read, ReadChannels, ReadLayers};
    check_exr_header(bytes)?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(IoCursor::new(bytes))
        .map_err(|e| image_err(format!("cannot read the OpenEXR file: {e}")))?;
    let layer = image.layer_data;
    let (w, h) = (layer.size.width(), layer.size.height());
    let (Ok(w32), Ok(h32)) = (u32::try_from(w), u32::try_from(h)) else {
        return Err(image_err(format!("the OpenEXR image is too large ({w}x{h})")));
    };
    let channels: Vec<(String, Vec<f32>)> =
        layer.channel_data.list.into_iter().map(|c| (c.name.to_string(), into_f32(c.sample_data))).collect();
    if let Some((name, _)) = channels.iter().find(|(_, v)| v.len() != w * h) {
        return Err(image_err(format!(
            "OpenEXR channel {name:?} is subsampled; hairrecon reads full-resolution channels"
        )));
    }
    if channels.is_empty() {
        return Err(image_err("the OpenEXR file has no channels"));
    }
    Ok(Decoded::Exr(w32, h32, channels))
}

/// A channel's samples as `f32`, moved rather than copied when they are `f32` already (a large
/// image is held once, not twice).
fn into_f32(samples: exr::prelude::FlatSamples) -> Vec<f32> {
    match samples {
        exr::prelude::FlatSamples::F32(v) => v,
        other => other.values_as_f32().collect(),
    }
}

fn take_channel(channels: &mut Vec<(String, Vec<f32>)>, name: &str) -> Option<Vec<f32>> {
    let i = channels.iter().position(|(n, _)| n == name)?;
    Some(channels.swap_remove(i).1)
}

fn exr_gray(mut channels: Vec<(String, Vec<f32>)>) -> Result<Vec<f32>> {
    if channels.len() == 1 {
        return Ok(channels.remove(0).1);
    }
    let names: Vec<String> = channels.iter().map(|(n, _)| n.clone()).collect();
    take_channel(&mut channels, "Y").or_else(|| take_channel(&mut channels, "R")).ok_or_else(|| {
        image_err(format!(
            "the OpenEXR file has channels {names:?} but no Y or R; read a named channel with read_exr_channel"
        ))
    })
}

/// Reads a one-channel float image from a PNG or OpenEXR file (see the module doc for which values).
pub fn read_gray_f32(path: impl AsRef<Path>) -> Result<GrayImage32> {
    let path = path.as_ref();
    let bytes = read_file(path)?;
    read_gray_f32_bytes(&bytes).map_err(|e| e.in_file(path))
}

/// [`read_gray_f32`] from memory.
pub fn read_gray_f32_bytes(bytes: &[u8]) -> Result<GrayImage32> {
    match decode(bytes)? {
        Decoded::Png(img) => {
            let (w, h) = (img.width(), img.height());
            let data = match img {
                image::DynamicImage::ImageLuma8(b) => b.into_raw().into_iter().map(|v| v as f32 / 255.0).collect(),
                image::DynamicImage::ImageLuma16(b) => b.into_raw().into_iter().map(|v| v as f32 / 65535.0).collect(),
                other => other.to_luma32f().into_raw(),
            };
            GrayImage32::new(w, h, data)
        }
        Decoded::Exr(w, h, channels) => GrayImage32::new(w, h, exr_gray(channels)?),
    }
}

/// Reads a three-channel float image from a PNG or OpenEXR file (see the module doc).
pub fn read_rgb_f32(path: impl AsRef<Path>) -> Result<RgbImage32> {
    let path = path.as_ref();
    let bytes = read_file(path)?;
    read_rgb_f32_bytes(&bytes).map_err(|e| e.in_file(path))
}

/// [`read_rgb_f32`] from memory.
pub fn read_rgb_f32_bytes(bytes: &[u8]) -> Result<RgbImage32> {
    match decode(bytes)? {
        Decoded::Png(img) => {
            let (w, h) = (img.width(), img.height());
            let data = match img {
                image::DynamicImage::ImageRgb8(b) => b.into_raw().into_iter().map(|v| v as f32 / 255.0).collect(),
                image::DynamicImage::ImageRgb16(b) => b.into_raw().into_iter().map(|v| v as f32 / 65535.0).collect(),
                other => other.to_rgb32f().into_raw(),
            };
            RgbImage32::new(w, h, data)
        }
        Decoded::Exr(w, h, mut channels) => {
            let rgb = match (
                take_channel(&mut channels, "R"),
                take_channel(&mut channels, "G"),
                take_channel(&mut channels, "B"),
            ) {
                (Some(r), Some(g), Some(b)) => [r, g, b],
                (r, g, b) => {
                    // Put back what was taken and read a gray image.
                    for (n, v) in [("R", r), ("G", g), ("B", b)] {
                        if let Some(v) = v {
                            channels.push((n.into(), v));
                        }
                    }
                    let y = exr_gray(channels)?;
                    [y.clone(), y.clone(), y]
                }
            };
            let mut data = Vec::with_capacity(3 * rgb[0].len());
            for i in 0..rgb[0].len() {
                data.extend([rgb[0][i], rgb[1][i], rgb[2][i]]);
            }
            RgbImage32::new(w, h, data)
        }
    }
}

/// Reads the channel called `name` of an OpenEXR file (e.g. `"Z"` or `"ViewLayer.Depth.Z"`).
pub fn read_exr_channel(path: impl AsRef<Path>, name: &str) -> Result<GrayImage32> {
    let path = path.as_ref();
    let bytes = read_file(path)?;
    let inner = || -> Result<GrayImage32> {
        match decode(&bytes)? {
            Decoded::Exr(w, h, mut channels) => {
                let names: Vec<String> = channels.iter().map(|(n, _)| n.clone()).collect();
                let data = take_channel(&mut channels, name)
                    .ok_or_else(|| image_err(format!("the OpenEXR file has no channel {name:?}; it has {names:?}")))?;
                GrayImage32::new(w, h, data)
            }
            Decoded::Png(_) => Err(image_err("this is a PNG file, not OpenEXR; read it with read_gray_f32")),
        }
    };
    inner().map_err(|e| e.in_file(path))
}

/// Checks values before quantising them: NaN cannot be written to PNG.
fn quantize<T>(data: &[f32], max: f32, conv: impl Fn(f32) -> T) -> Result<Vec<T>> {
    let mut out = Vec::with_capacity(data.len());
    for (i, &v) in data.iter().enumerate() {
        if v.is_nan() {
            return Err(invalid(format!("value {i} is NaN; PNG cannot store it (clean the image or write EXR)")));
        }
        out.push(conv((v.clamp(0.0, 1.0) * max).round()));
    }
    Ok(out)
}

fn write_png(path: &Path, width: u32, height: u32, bytes: &[u8], color: image::ExtendedColorType) -> Result<()> {
    use image::ImageEncoder;
    atomic_write(path, |w| {
        image::codecs::png::PngEncoder::new(w).write_image(bytes, width, height, color).map_err(image_err)
    })
}

/// Writes an 8-bit gray PNG (values clamped to `[0, 1]`, then rounded to 0..=255).
pub fn write_png8_gray(path: impl AsRef<Path>, img: &GrayImage32) -> Result<()> {
    let path = path.as_ref();
    check_size(img.width, img.height, 1, img.data.len()).map_err(|e| e.in_file(path))?;
    let q = quantize(&img.data, 255.0, |v| v as u8).map_err(|e| e.in_file(path))?;
    write_png(path, img.width, img.height, &q, image::ExtendedColorType::L8)
}

/// Writes a 16-bit gray PNG (values clamped to `[0, 1]`, then rounded to 0..=65535).
pub fn write_png16_gray(path: impl AsRef<Path>, img: &GrayImage32) -> Result<()> {
    let path = path.as_ref();
    check_size(img.width, img.height, 1, img.data.len()).map_err(|e| e.in_file(path))?;
    let q = quantize(&img.data, 65535.0, |v| v as u16).map_err(|e| e.in_file(path))?;
    // The encoder takes 16-bit samples in native byte order.
    let bytes: Vec<u8> = q.iter().flat_map(|v| v.to_ne_bytes()).collect();
    write_png(path, img.width, img.height, &bytes, image::ExtendedColorType::L16)
}

/// Writes an 8-bit RGB PNG (values clamped to `[0, 1]`, then rounded to 0..=255).
pub fn write_png8_rgb(path: impl AsRef<Path>, img: &RgbImage32) -> Result<()> {
    let path = path.as_ref();
    check_size(img.width, img.height, 3, img.data.len()).map_err(|e| e.in_file(path))?;
    let q = quantize(&img.data, 255.0, |v| v as u8).map_err(|e| e.in_file(path))?;
    write_png(path, img.width, img.height, &q, image::ExtendedColorType::Rgb8)
}

fn write_exr(path: &Path, width: u32, height: u32, channels: Vec<(&str, Vec<f32>)>) -> Result<()> {
    use exr::prelude::{AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, WritableImage};
    let list: Vec<AnyChannel<FlatSamples>> =
        channels.into_iter().map(|(n, v)| AnyChannel::new(n, FlatSamples::F32(v))).collect();
    let layer = Layer::new(
        (width as usize, height as usize),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(list.into()),
    );
    let image = Image::from_layer(layer);
    atomic_write(path, |w| image.write().to_buffered(w).map_err(|e| image_err(format!("cannot write OpenEXR: {e}"))))
}

/// Writes a one-channel (`Y`) 32-bit float OpenEXR file, values unchanged.
pub fn write_exr_gray_f32(path: impl AsRef<Path>, img: &GrayImage32) -> Result<()> {
    let path = path.as_ref();
    check_size(img.width, img.height, 1, img.data.len()).map_err(|e| e.in_file(path))?;
    write_exr(path, img.width, img.height, vec![("Y", img.data.clone())])
}

/// Writes an `R G B` 32-bit float OpenEXR file, values unchanged.
pub fn write_exr_rgb_f32(path: impl AsRef<Path>, img: &RgbImage32) -> Result<()> {
    let path = path.as_ref();
    check_size(img.width, img.height, 3, img.data.len()).map_err(|e| e.in_file(path))?;
    let plane = |c: usize| img.data.iter().skip(c).step_by(3).copied().collect::<Vec<f32>>();
    write_exr(path, img.width, img.height, vec![("R", plane(0)), ("G", plane(1)), ("B", plane(2))])
}

/// The samples of a [`RawImage`], in the file's own type.
#[derive(Debug, Clone, PartialEq)]
pub enum Samples {
    U8(Vec<u8>),
    U16(Vec<u16>),
    F32(Vec<f32>),
}

impl Samples {
    /// The number of samples.
    pub fn len(&self) -> usize {
        match self {
            Samples::U8(v) => v.len(),
            Samples::U16(v) => v.len(),
            Samples::F32(v) => v.len(),
        }
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn type_name(&self) -> &'static str {
        match self {
            Samples::U8(_) => "8-bit integer",
            Samples::U16(_) => "16-bit integer",
            Samples::F32(_) => "32-bit float",
        }
    }
}

/// An image as stored in its file: row-major, top row first, `channels` interleaved samples per
/// pixel (`samples[channels * (y * width + x) + c]`).
#[derive(Debug, Clone, PartialEq)]
pub struct RawImage {
    pub width: u32,
    pub height: u32,
    pub channels: usize,
    pub samples: Samples,
}

impl RawImage {
    /// Builds an image, checking the size, 1 to 4 channels and the number of samples.
    pub fn new(width: u32, height: u32, channels: usize, samples: Samples) -> Result<Self> {
        if !(1..=4).contains(&channels) {
            return Err(invalid(format!("an image has 1 to 4 channels, got {channels}")));
        }
        check_size(width, height, channels, samples.len())?;
        Ok(Self { width, height, channels, samples })
    }
}

/// The named channels of an OpenEXR file, each `width * height` values, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct ExrChannels {
    pub width: u32,
    pub height: u32,
    pub channels: Vec<(String, Vec<f32>)>,
}

/// Reads an image with its own samples (see the module doc): PNG as 8/16-bit integers with its 1 to 4
/// channels; OpenEXR as `f32`, channels `R G B` (and `A` when there is one), else `Y` (and `A`), else
/// the file's only channel. The type is taken from the file's first bytes.
pub fn read_image(path: impl AsRef<Path>) -> Result<RawImage> {
    let path = path.as_ref();
    let bytes = read_file(path)?;
    read_image_bytes(&bytes).map_err(|e| e.in_file(path))
}

/// [`read_image`] from memory.
pub fn read_image_bytes(bytes: &[u8]) -> Result<RawImage> {
    use image::DynamicImage as D;
    if !bytes.starts_with(PNG_MAGIC) {
        let exr = read_exr_channels_bytes(bytes)?;
        return exr_to_raw(exr);
    }
    let img = match decode(bytes)? {
        Decoded::Png(img) => img,
        Decoded::Exr(..) => unreachable!("a PNG signature decodes as PNG"),
    };
    let (w, h) = (img.width(), img.height());
    let (channels, samples) = match img {
        D::ImageLuma8(b) => (1, Samples::U8(b.into_raw())),
        D::ImageLumaA8(b) => (2, Samples::U8(b.into_raw())),
        D::ImageRgb8(b) => (3, Samples::U8(b.into_raw())),
        D::ImageRgba8(b) => (4, Samples::U8(b.into_raw())),
        D::ImageLuma16(b) => (1, Samples::U16(b.into_raw())),
        D::ImageLumaA16(b) => (2, Samples::U16(b.into_raw())),
        D::ImageRgb16(b) => (3, Samples::U16(b.into_raw())),
        D::ImageRgba16(b) => (4, Samples::U16(b.into_raw())),
        D::ImageRgb32F(b) => (3, Samples::F32(b.into_raw())),
        D::ImageRgba32F(b) => (4, Samples::F32(b.into_raw())),
        other => (4, Samples::F32(other.to_rgba32f().into_raw())),
    };
    RawImage::new(w, h, channels, samples)
}

fn exr_to_raw(exr: ExrChannels) -> Result<RawImage> {
    let ExrChannels { width, height, mut channels } = exr;
    let names: Vec<String> = channels.iter().map(|(n, _)| n.clone()).collect();
    let has = |n: &str| names.iter().any(|m| m == n);
    let pick: Vec<&str> = if has("R") && has("G") && has("B") {
        if has("A") {
            vec!["R", "G", "B", "A"]
        } else {
            vec!["R", "G", "B"]
        }
    } else if has("Y") {
        if has("A") {
            vec!["Y", "A"]
        } else {
            vec!["Y"]
        }
    } else if channels.len() == 1 {
        vec![]
    } else {
        return Err(image_err(format!(
            "the OpenEXR file has channels {names:?}, not R G B [A] or Y [A]; read them by name \
             (read_exr_channels; Python: hairrecon.read_exr)"
        )));
    };
    let planes: Vec<Vec<f32>> = if pick.is_empty() {
        vec![channels.remove(0).1]
    } else {
        pick.iter().map(|n| take_channel(&mut channels, n).expect("checked above")).collect()
    };
    let n = planes[0].len();
    let mut data = Vec::with_capacity(n * planes.len());
    for i in 0..n {
        data.extend(planes.iter().map(|p| p[i]));
    }
    RawImage::new(width, height, planes.len(), Samples::F32(data))
}

/// Reads every channel of every layer of an OpenEXR file (largest resolution level), as `f32`. The
/// names are the file's own (Blender's multilayer files name them `ViewLayer.Combined.R`, ...); when
/// the file has several layers (parts), a channel whose name does not already start with its layer's
/// name gets that name as prefix (`layer.R`). All layers must have one size.
pub fn read_exr_channels(path: impl AsRef<Path>) -> Result<ExrChannels> {
    let path = path.as_ref();
    let bytes = read_file(path)?;
    read_exr_channels_bytes(&bytes).map_err(|e| e.in_file(path))
}

/// [`read_exr_channels`] from memory.
pub fn read_exr_channels_bytes(bytes: &[u8]) -> Result<ExrChannels> {
    if !bytes.starts_with(EXR_MAGIC) {
        if bytes.starts_with(PNG_MAGIC) {
            return Err(image_err("this is a PNG file, not OpenEXR; read it with read_image"));
        }
        let found = String::from_utf8_lossy(&bytes[..bytes.len().min(8)]).into_owned();
        return Err(
            FormatErrorKind::BadMagic { format: "PNG or OpenEXR", expected: "\\x89PNG or v/1\\x01", found }.into()
        );
    }
    check_exr_header(bytes)?;
    guarded(|| {
        use exr::prelude::{read, ReadChannels, ReadLayers};
        let image = read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .all_layers()
            .all_attributes()
            .from_buffered(IoCursor::new(bytes))
            .map_err(|e| image_err(format!("cannot read the OpenEXR file: {e}")))?;
        let several = image.layer_data.len() > 1;
        let mut size = None;
        let mut channels: Vec<(String, Vec<f32>)> = Vec::new();
        for layer in image.layer_data {
            let (w, h) = (layer.size.width(), layer.size.height());
            match size {
                None => size = Some((w, h)),
                Some(s) if s != (w, h) => {
                    return Err(image_err(format!(
                        "the OpenEXR file's layers have different sizes ({}x{} and {w}x{h}); hairrecon reads \
                         layers of one size",
                        s.0, s.1
                    )))
                }
                Some(_) => {}
            }
            let prefix =
                layer.attributes.layer_name.as_ref().map(|n| n.to_string()).filter(|n| several && !n.is_empty());
            for c in layer.channel_data.list {
                let mut name = c.name.to_string();
                if let Some(p) = &prefix {
                    if !name.starts_with(&format!("{p}.")) {
                        name = format!("{p}.{name}");
                    }
                }
                let values = into_f32(c.sample_data);
                if values.len() != w * h {
                    return Err(image_err(format!(
                        "OpenEXR channel {name:?} is subsampled; hairrecon reads full-resolution channels"
                    )));
                }
                if channels.iter().any(|(n, _)| *n == name) {
                    return Err(image_err(format!("the OpenEXR file has two channels named {name:?}")));
                }
                channels.push((name, values));
            }
        }
        let (w, h) = size.ok_or_else(|| image_err("the OpenEXR file has no layers"))?;
        if channels.is_empty() {
            return Err(image_err("the OpenEXR file has no channels"));
        }
        let (Ok(width), Ok(height)) = (u32::try_from(w), u32::try_from(h)) else {
            return Err(image_err(format!("the OpenEXR image is too large ({w}x{h})")));
        };
        Ok(ExrChannels { width, height, channels })
    })
}

/// Writes named `f32` channels (each `width * height` values, row-major) as a 32-bit float OpenEXR
/// file with lossless ZIP compression, values unchanged. Channel names must be unique and non-empty.
pub fn write_exr_channels(path: impl AsRef<Path>, exr: &ExrChannels) -> Result<()> {
    let path = path.as_ref();
    let check = || -> Result<()> {
        if exr.channels.is_empty() {
            return Err(invalid("an OpenEXR file needs at least one channel".into()));
        }
        for (i, (name, values)) in exr.channels.iter().enumerate() {
            if name.is_empty() || exr.channels[..i].iter().any(|(n, _)| n == name) {
                return Err(invalid(format!("OpenEXR channel names must be unique and non-empty, got {name:?}")));
            }
            check_size(exr.width, exr.height, 1, values.len())
                .map_err(|e| invalid(format!("channel {name:?}: {}", e.kind)))?;
        }
        Ok(())
    };
    check().map_err(|e| e.in_file(path))?;
    let channels = exr.channels.iter().map(|(n, v)| (n.as_str(), v.clone())).collect();
    write_exr(path, exr.width, exr.height, channels)
}

/// The OpenEXR channel names [`write_image`] gives 1 to 4 channels: `Y`, `Y A`, `R G B`, `R G B A`.
pub fn default_channel_names(channels: usize) -> &'static [&'static str] {
    match channels {
        1 => &["Y"],
        2 => &["Y", "A"],
        3 => &["R", "G", "B"],
        _ => &["R", "G", "B", "A"],
    }
}

/// Writes an image as stored, by the file's extension: `.png` takes 8- or 16-bit samples with 1 to 4
/// channels (gray, gray + alpha, RGB, RGBA) and writes them unchanged; `.exr` takes `f32` samples and
/// writes them as 32-bit float channels named `names`, or by [`default_channel_names`]. Atomic.
pub fn write_image(path: impl AsRef<Path>, img: &RawImage, names: Option<&[String]>) -> Result<()> {
    use image::ExtendedColorType as C;
    let path = path.as_ref();
    let fail = |e: FormatError| e.in_file(path);
    check_size(img.width, img.height, img.channels, img.samples.len()).map_err(fail)?;
    if !(1..=4).contains(&img.channels) {
        return Err(fail(invalid(format!("an image has 1 to 4 channels, got {}", img.channels))));
    }
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).unwrap_or_default();
    match ext.as_str() {
        "png" => {
            if names.is_some() {
                return Err(fail(invalid(
                    "channel names are for OpenEXR; a PNG's channels are gray, gray + alpha, RGB or RGBA by their count"
                        .into(),
                )));
            }
            let (bytes, color) = match &img.samples {
                Samples::U8(v) => (v.clone(), [C::L8, C::La8, C::Rgb8, C::Rgba8][img.channels - 1]),
                // The encoder takes 16-bit samples in native byte order.
                Samples::U16(v) => (
                    v.iter().flat_map(|s| s.to_ne_bytes()).collect(),
                    [C::L16, C::La16, C::Rgb16, C::Rgba16][img.channels - 1],
                ),
                Samples::F32(_) => return Err(fail(invalid(
                    "PNG stores 8- or 16-bit integers, not floats: convert the values (e.g. to uint16) or write .exr"
                        .into(),
                ))),
            };
            write_png(path, img.width, img.height, &bytes, color)
        }
        "exr" => {
            let Samples::F32(data) = &img.samples else {
                return Err(fail(invalid(format!(
                    "OpenEXR stores floats; got {} samples (convert them to float32, or write .png)",
                    img.samples.type_name()
                ))));
            };
            let names: Vec<String> = match names {
                Some(n) if n.len() != img.channels => {
                    return Err(fail(invalid(format!(
                        "{} channel names for an image of {} channels",
                        n.len(),
                        img.channels
                    ))))
                }
                Some(n) => n.to_vec(),
                None => default_channel_names(img.channels).iter().map(|s| s.to_string()).collect(),
            };
            let channels = names
                .into_iter()
                .enumerate()
                .map(|(c, n)| (n, data.iter().skip(c).step_by(img.channels).copied().collect()))
                .collect();
            write_exr_channels(path, &ExrChannels { width: img.width, height: img.height, channels })
        }
        other => {
            Err(fail(FormatErrorKind::UnknownExtension { ext: format!(".{other}"), supported: ".png, .exr" }.into()))
        }
    }
}
