//! Photo loading and resampling against analytic images.
//!
//! Scaling: one physical pinhole camera (focal length and principal point in units of the sensor's
//! width and height) sampled at two resolutions, each pixel the average of the scene over its
//! square; the large image resampled to the small size must match the small one and its returned K
//! must be the one the physical camera implies. Undistortion: a scene seen through a distorted
//! camera (each pixel's ray found with `Distortion::undistort`), undistorted by `resample`, must
//! match the same scene seen by the pinhole camera.

use std::path::PathBuf;

use hairrecon_core::image_io::RgbImage32;
use hairrecon_import::photo::{load_photo, resample, Orientation, PhotoError, PhotoPixels, Prefer};
use hairrecon_import::{Distortion, Intrinsics};

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("hairrecon-import-photo-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

// ---------------------------------------------------------------------------------------------
// Scaling

/// The camera in sensor units: normalized `x = (a − CA) / FA` where `a ∈ [0, 1]` runs across the
/// sensor's width (and `b` down its height).
const FA: f64 = 0.9;
const FB: f64 = 1.2;
const CA: f64 = 0.47;
const CB: f64 = 0.53;

/// K of the physical camera sampled at `w` x `h` pixels: pixel centre `i` is at `a = (i + ½)/w`.
fn physical_k(w: u32, h: u32) -> Intrinsics {
    Intrinsics { fx: FA * w as f64, fy: FB * h as f64, cx: CA * w as f64 - 0.5, cy: CB * h as f64 - 0.5, skew: 0.0 }
}

/// Where the marker is seen, in normalized coordinates.
const MARK: (f64, f64) = (0.061, -0.043);

/// The scene along normalized ray `(x, y)`: a tilted textured plane (smooth stripes in G, a
/// checker in B) and a Gaussian marker in R.
fn scene(x: f64, y: f64) -> [f64; 3] {
    // the plane n·X = 2 with n tilted 25° about the camera's y axis
    let (s, c) = 25f64.to_radians().sin_cos();
    let t = 2.0 / (s * x + c);
    let (px, py, pz) = (t * x, t * y, t);
    // in-plane coordinates along (c, 0, -s) and (0, 1, 0)
    let (pu, pv) = (c * px - s * pz, py);
    let stripes = 0.5 + 0.25 * (pu * 40.0).sin() + 0.2 * (pv * 31.0 + 0.3).cos();
    let checker = if ((pu * 6.0).floor() + (pv * 6.0).floor()) as i64 % 2 == 0 { 0.8 } else { 0.2 };
    let sigma = 0.009; // about 2 pixels of the small image
    let d2 = (x - MARK.0).powi(2) + (y - MARK.1).powi(2);
    [(-d2 / (2.0 * sigma * sigma)).exp(), stripes, checker]
}

/// The image of [`scene`] at `w` x `h` pixels, each pixel the mean of an `n` x `n` grid over its
/// square, as 16-bit RGB (so that quantization stays far below the differences measured).
fn render(w: u32, h: u32, n: u32) -> image::ImageBuffer<image::Rgb<u16>, Vec<u16>> {
    let k = physical_k(w, h);
    image::ImageBuffer::from_fn(w, h, |i, j| {
        let mut acc = [0.0; 3];
        for b in 0..n {
            for a in 0..n {
                let u = i as f64 + (a as f64 + 0.5) / n as f64 - 0.5;
                let v = j as f64 + (b as f64 + 0.5) / n as f64 - 0.5;
                let s = scene((u - k.cx) / k.fx, (v - k.cy) / k.fy);
                for c in 0..3 {
                    acc[c] += s[c];
                }
            }
        }
        image::Rgb(acc.map(|a| (a / (n * n) as f64 * 65535.0).round() as u16))
    })
}

/// Intensity-weighted centroid of channel `c` in a `radius` window around `(u, v)`.
fn centroid(img: &RgbImage32, c: usize, (u, v): (f64, f64), radius: i64) -> (f64, f64) {
    let (mut sw, mut su, mut sv) = (0.0, 0.0, 0.0);
    for j in (v.round() as i64 - radius)..=(v.round() as i64 + radius) {
        for i in (u.round() as i64 - radius)..=(u.round() as i64 + radius) {
            let val = img.get(i as u32, j as u32)[c] as f64;
            sw += val;
            su += val * i as f64;
            sv += val * j as f64;
        }
    }
    (su / sw, sv / sw)
}

fn to_f32(img: &image::ImageBuffer<image::Rgb<u16>, Vec<u16>>) -> RgbImage32 {
    RgbImage32 {
        width: img.width(),
        height: img.height(),
        data: img.as_raw().iter().map(|&v| v as f32 / 65535.0).collect(),
    }
}

#[test]
fn downscaling_matches_the_camera_sampled_at_the_small_size() {
    let (big_w, big_h) = (1200, 900);
    let target = 200; // a factor of 4.5; width 267 (scales 0.2225 and 0.2222 differ by the rounding)
    let big = render(big_w, big_h, 3);
    let out = resample(&PhotoPixels::Rgb16(big), &physical_k(big_w, big_h), &Distortion::default(), target).unwrap();
    let (w, h) = (out.image.width, out.image.height);
    assert_eq!((w, h, out.samples_per_axis), (267, 200, 5));
    assert!(out.coverage.data.iter().all(|&c| c == 1.0));

    // the returned K is the physical camera's at the small size
    let expected = physical_k(w, h);
    let k = out.intrinsics;
    for (got, want) in [(k.fx, expected.fx), (k.fy, expected.fy), (k.cx, expected.cx), (k.cy, expected.cy)] {
        assert!((got - want).abs() < 1e-9, "{k:?} vs {expected:?}");
    }

    // the pixels are the small camera's
    let small = to_f32(&render(w, h, 16));
    let mut sums = [0.0f64; 3];
    for (i, (a, b)) in out.image.data.iter().zip(&small.data).enumerate() {
        sums[i % 3] += (a - b).abs() as f64;
    }
    let n = (w * h) as f64;
    let mad = sums.map(|s| s / n * 255.0);
    println!("mean abs diff in grey levels of 255: marker {:.3}, stripes {:.3}, checker {:.3}", mad[0], mad[1], mad[2]);
    assert!(mad[0] < 0.05 && mad[1] < 0.2 && mad[2] < 1.0, "{mad:?}");

    // the marker is where the returned K projects it, to 0.01 pixel
    let proj = (k.fx * MARK.0 + k.cx, k.fy * MARK.1 + k.cy);
    let (cu, cv) = centroid(&out.image, 0, proj, 12);
    let (du, dv) = centroid(&small, 0, proj, 12);
    println!(
        "marker: projected ({:.5}, {:.5}), resampled ({cu:.5}, {cv:.5}), rendered small ({du:.5}, {dv:.5})",
        proj.0, proj.1
    );
    assert!((cu - proj.0).abs() < 0.01 && (cv - proj.1).abs() < 0.01);
    assert!((du - proj.0).abs() < 0.01 && (dv - proj.1).abs() < 0.01, "the reference itself");
}

#[test]
fn a_single_bilinear_tap_would_alias_the_box_filter_does_not() {
    // a grating at 0.8 of the large image's Nyquist frequency averages out to mid-grey at 1/8 scale
    let big = image::ImageBuffer::from_fn(800, 800, |i, _| {
        let v = 0.5 + 0.5 * (std::f64::consts::PI * 0.8 * i as f64).cos();
        image::Rgb([(v * 65535.0).round() as u16; 3])
    });
    let k = Intrinsics { fx: 800.0, fy: 800.0, cx: 399.5, cy: 399.5, skew: 0.0 };
    let out = resample(&PhotoPixels::Rgb16(big), &k, &Distortion::default(), 100).unwrap();
    let worst = out.image.data.iter().map(|&v| (v - 0.5).abs()).fold(0.0f32, f32::max);
    println!("grating at 1/8 scale: largest deviation from grey {:.4}", worst);
    assert!(worst < 0.05, "aliasing: {worst}");
}

// ---------------------------------------------------------------------------------------------
// Undistortion

/// Low-frequency sinusoids over normalized coordinates.
fn smooth_scene(x: f64, y: f64) -> [f64; 3] {
    [
        0.5 + 0.4 * (9.0 * x + 1.0).sin() * (7.0 * y).cos(),
        0.5 + 0.4 * (11.0 * y - 0.5).sin(),
        0.5 + 0.3 * (6.0 * (x + y)).cos(),
    ]
}

#[test]
fn undistortion_matches_the_pinhole_camera() {
    let (w, h) = (640u32, 480u32);
    let k = Intrinsics { fx: 520.0, fy: 515.0, cx: 322.3, cy: 236.8, skew: 0.0 };
    let dist = Distortion { k: [-0.1, 0.02, 0.0, 0.0], d: [0.0; 3], p: [1e-3, 1e-3] };
    let r_valid = dist.valid_radius();
    // what the distorted camera records: each pixel's ray, the scene along it
    let photo = image::ImageBuffer::from_fn(w, h, |i, j| {
        let (xd, yd) = ((i as f64 - k.cx) / k.fx, (j as f64 - k.cy) / k.fy);
        let (x, y) = dist.undistort_within(xd, yd, r_valid).expect("inside the image");
        image::Rgb(smooth_scene(x, y).map(|v| (v * 65535.0).round() as u16))
    });
    let photo = PhotoPixels::Rgb16(photo);
    for target in [480, 240] {
        let out = resample(&photo, &k, &dist, target).unwrap();
        let nk = out.intrinsics;
        let margin = 8 * target / 480;
        let (mut sum, mut n, mut worst) = (0.0f64, 0usize, 0.0f64);
        for j in margin..out.image.height - margin {
            for i in margin..out.image.width - margin {
                if out.coverage.get(i, j) < 1.0 {
                    continue;
                }
                let want = smooth_scene((i as f64 - nk.cx) / nk.fx, (j as f64 - nk.cy) / nk.fy);
                let got = out.image.get(i, j);
                for c in 0..3 {
                    let d = (got[c] as f64 - want[c]).abs() * 255.0;
                    sum += d;
                    worst = worst.max(d);
                    n += 1;
                }
            }
        }
        let covered = n / 3;
        let total = ((out.image.width - 2 * margin) * (out.image.height - 2 * margin)) as usize;
        let mad = sum / n as f64;
        println!("undistorted at height {target}: mean abs diff {mad:.4} grey levels (worst {worst:.3}) over {covered} of {total} pixels inside the margin");
        assert!(covered as f64 > 0.95 * total as f64, "barrel distortion crops: the pinhole image is covered");
        assert!(mad < 1.0, "{mad}");
        // without undistorting, the same comparison is far off: the test can fail
        let plain = resample(&photo, &k, &Distortion::default(), target).unwrap();
        let mut off = 0.0f64;
        for j in margin..plain.image.height - margin {
            for i in margin..plain.image.width - margin {
                let want = smooth_scene((i as f64 - nk.cx) / nk.fx, (j as f64 - nk.cy) / nk.fy);
                off += (plain.image.get(i, j)[0] as f64 - want[0]).abs() * 255.0;
            }
        }
        assert!(off / total as f64 > 5.0 * mad.max(0.2), "ignoring the distortion: {}", off / total as f64);
    }
}

// ---------------------------------------------------------------------------------------------
// Loading

/// A baseline JPEG of `img` with an APP1 Exif segment holding only Orientation = `orientation`
/// (a big-endian TIFF header and one IFD entry), inserted right after SOI.
fn jpeg_with_orientation(img: &image::RgbImage, orientation: u16) -> Vec<u8> {
    let mut jpeg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 95).encode_image(img).unwrap();
    let mut tiff = b"MM\x00\x2a\x00\x00\x00\x08".to_vec(); // big-endian, IFD0 at offset 8
    tiff.extend_from_slice(&1u16.to_be_bytes()); // one entry
    tiff.extend_from_slice(&0x0112u16.to_be_bytes()); // Orientation
    tiff.extend_from_slice(&3u16.to_be_bytes()); // SHORT
    tiff.extend_from_slice(&1u32.to_be_bytes()); // count
    tiff.extend_from_slice(&orientation.to_be_bytes());
    tiff.extend_from_slice(&[0, 0]); // value padding
    tiff.extend_from_slice(&0u32.to_be_bytes()); // no next IFD
    let mut payload = b"Exif\x00\x00".to_vec();
    payload.extend_from_slice(&tiff);
    let mut out = jpeg[..2].to_vec();
    out.extend_from_slice(&[0xFF, 0xE1]);
    out.extend_from_slice(&((payload.len() + 2) as u16).to_be_bytes());
    out.extend_from_slice(&payload);
    out.extend_from_slice(&jpeg[2..]);
    out
}

fn is_red(p: &image::Rgb<u8>) -> bool {
    p.0[0] > 200 && p.0[1] < 60 && p.0[2] < 60
}

#[test]
fn exif_orientation_is_read_and_the_calibrations_size_picks_the_pixels() {
    let dir = tmp("exif");
    // stored 64 x 48, the top-left 16 x 16 block red, the rest blue
    let img = image::RgbImage::from_fn(64, 48, |x, y| {
        if x < 16 && y < 16 {
            image::Rgb([255, 0, 0])
        } else {
            image::Rgb([0, 0, 255])
        }
    });
    let path = dir.join("IMG_0001.JPG");
    std::fs::write(&path, jpeg_with_orientation(&img, 6)).unwrap();
    let photo = load_photo(&path).unwrap();
    assert_eq!(photo.orientation, Orientation::Rotate90);
    assert_eq!(photo.exif_orientation(), 6);
    assert_eq!((photo.width(), photo.height(), photo.oriented_size()), (64, 48, (48, 64)));

    // a camera calibrated on the stored pixels gets them as they are
    let PhotoPixels::Rgb8(stored) = photo.oriented_to(64, 48).unwrap().into_owned() else { panic!("8-bit") };
    assert!(is_red(stored.get_pixel(8, 8)) && !is_red(stored.get_pixel(56, 8)));
    // a camera calibrated on the displayed photo gets it rotated 90° clockwise: red at top right
    let PhotoPixels::Rgb8(shown) = photo.oriented_to(48, 64).unwrap().into_owned() else { panic!("8-bit") };
    assert_eq!((shown.width(), shown.height()), (48, 64));
    assert!(is_red(shown.get_pixel(40, 8)), "{:?}", shown.get_pixel(40, 8));
    assert!(!is_red(shown.get_pixel(8, 8)) && !is_red(shown.get_pixel(40, 56)));
    // neither: the error names the photo, both sizes and what to do
    let err = photo.oriented_to(6000, 4000).unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, PhotoError::SizeMismatch { .. }));
    assert!(msg.contains("IMG_0001.JPG") && msg.contains("64x48") && msg.contains("6000x4000"), "{msg}");
    assert!(msg.contains("calibration was made from"), "{msg}");

    // orientation 3 (180°) keeps the size: the stored pixels unless the EXIF ones are asked for
    std::fs::write(&path, jpeg_with_orientation(&img, 3)).unwrap();
    let photo = load_photo(&path).unwrap();
    assert_eq!(photo.orientation, Orientation::Rotate180);
    let PhotoPixels::Rgb8(p) = photo.oriented_to(64, 48).unwrap().into_owned() else { panic!() };
    assert!(is_red(p.get_pixel(8, 8)));
    let PhotoPixels::Rgb8(p) = photo.oriented_to_preferring(64, 48, Prefer::Exif).unwrap().into_owned() else {
        panic!()
    };
    assert!(is_red(p.get_pixel(56, 40)) && !is_red(p.get_pixel(8, 8)));

    // without the segment: orientation 1
    let mut plain = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut plain, 95).encode_image(&img).unwrap();
    std::fs::write(&path, plain).unwrap();
    assert_eq!(load_photo(&path).unwrap().orientation, Orientation::NoTransforms);
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn sixteen_bit_png_and_tiff_and_eight_bit_variants_load_exactly() {
    let dir = tmp("formats");
    let rgb16 = image::ImageBuffer::from_fn(7, 5, |x, y| {
        image::Rgb([(x * 9000 + 7) as u16, (y * 12000 + 3) as u16, 65535 - (x * y * 100) as u16])
    });
    for ext in ["png", "tiff"] {
        let path = dir.join(format!("rgb16.{ext}"));
        rgb16.save(&path).unwrap();
        let photo = load_photo(&path).unwrap();
        assert_eq!(photo.pixels, PhotoPixels::Rgb16(rgb16.clone()), "{ext}");
        assert_eq!(photo.orientation, Orientation::NoTransforms);
        // 16-bit samples scale to [0, 1] by 65,535
        let k = Intrinsics { fx: 7.0, fy: 7.0, cx: 3.0, cy: 2.0, skew: 0.0 };
        let out = resample(&photo.pixels, &k, &Distortion::default(), 5).unwrap();
        assert!((out.image.get(6, 4)[0] - (6.0 * 9000.0 + 7.0) / 65535.0).abs() < 1e-6);
    }
    // gray 16-bit repeats into three channels; RGBA 8-bit drops alpha; 8-bit TIFF stays 8-bit
    let gray16 = image::ImageBuffer::from_fn(4, 3, |x, y| image::Luma([(x * 10000 + y * 3000) as u16]));
    let path = dir.join("gray16.png");
    gray16.save(&path).unwrap();
    let PhotoPixels::Rgb16(p) = load_photo(&path).unwrap().pixels else { panic!("16-bit") };
    assert_eq!(p.get_pixel(3, 2).0, [36000; 3]);
    let rgba = image::RgbaImage::from_fn(4, 3, |x, _| image::Rgba([x as u8 * 50, 7, 9, 128]));
    let path = dir.join("rgba.png");
    rgba.save(&path).unwrap();
    let PhotoPixels::Rgb8(p) = load_photo(&path).unwrap().pixels else { panic!("8-bit") };
    assert_eq!(p.get_pixel(2, 1).0, [100, 7, 9]);
    let rgb8 = image::RgbImage::from_fn(4, 3, |x, y| image::Rgb([x as u8, y as u8, 200]));
    let path = dir.join("rgb8.tif");
    rgb8.save(&path).unwrap();
    assert_eq!(load_photo(&path).unwrap().pixels, PhotoPixels::Rgb8(rgb8));
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn broken_photos_are_errors_that_name_the_file() {
    let dir = tmp("broken");
    let img = image::RgbImage::from_fn(96, 64, |x, y| image::Rgb([(x * 2) as u8, (y * 3) as u8, (x ^ y) as u8]));
    let mut jpeg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 90).encode_image(&img).unwrap();
    let path = dir.join("cut.jpg");
    std::fs::write(&path, &jpeg[..jpeg.len() * 2 / 3]).unwrap();
    let err = load_photo(&path).unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, PhotoError::Unreadable { .. }), "{err:?}");
    assert!(msg.contains("cut.jpg") && msg.contains("truncated"), "{msg}");

    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).unwrap();
    let path = dir.join("cut.png");
    std::fs::write(&path, &png[..png.len() / 2]).unwrap();
    let err = load_photo(&path).unwrap_err();
    assert!(matches!(err, PhotoError::Unreadable { .. }) && err.to_string().contains("cut.png"), "{err}");

    let path = dir.join("notes.jpg");
    std::fs::write(&path, "not a photo").unwrap();
    let err = load_photo(&path).unwrap_err();
    assert!(matches!(err, PhotoError::Unsupported { .. }) && err.to_string().contains("notes.jpg"), "{err}");

    let float = image::Rgb32FImage::from_pixel(3, 2, image::Rgb([0.25, 0.5, 2.0]));
    let path = dir.join("float.tif");
    image::DynamicImage::ImageRgb32F(float).save(&path).unwrap();
    let err = load_photo(&path).unwrap_err();
    assert!(matches!(err, PhotoError::Unsupported { .. }) && err.to_string().contains("float.tif"), "{err}");

    let err = load_photo(dir.join("absent.jpg")).unwrap_err();
    assert!(matches!(err, PhotoError::Missing { .. }) && err.to_string().contains("absent.jpg"), "{err}");
    std::fs::remove_dir_all(dir).ok();
}

/// A PNG header (found by the fuzzer, `scripts/fuzz.sh`) claiming 245 x 134,217,736 pixels: the
/// photo is refused from its header, naming its size, without allocating 33 GB.
#[test]
fn a_photo_claiming_too_many_pixels_is_refused_before_decoding() {
    let dir = tmp("huge");
    let path = dir.join("huge.png");
    std::fs::write(&path, include_bytes!("data/png_header_claims_4_gigapixels.png")).unwrap();
    match load_photo(&path) {
        Err(e @ PhotoError::TooLarge { width: 245, height: 134_217_736, .. }) => {
            let msg = e.to_string();
            assert!(msg.contains("huge.png") && msg.contains("scale it down"), "{msg}");
        }
        other => panic!("expected TooLarge, got {other:?}"),
    }
    std::fs::remove_dir_all(dir).ok();
}
