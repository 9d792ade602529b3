//! Peak memory of loading a 6000x4000 JPEG and resampling it to 512 pixels high.
//!
//! ```text
//! cargo run -p hairrecon-import --release --example photo_memory
//! ```
//!
//! Writes the JPEG (with an EXIF orientation of 6) to the temporary folder, then measures in child
//! processes, so that making the test photo does not count: each loads it, takes the orientation a
//! camera of the given size asks for, undistorts and resamples it, and prints the process's peak
//! resident memory (Linux `VmHWM`) and the time taken.

use std::path::Path;
use std::process::Command;
use std::time::Instant;

use hairrecon_import::photo::{load_photo, resample};
use hairrecon_import::{Distortion, Intrinsics};

const W: u32 = 6000;
const H: u32 = 4000;

fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// A JPEG of a textured pattern with an APP1 Exif segment holding Orientation = 6.
fn write_photo(path: &Path) {
    let img = image::RgbImage::from_fn(W, H, |x, y| {
        let n = (x.wrapping_mul(2654435761) ^ y.wrapping_mul(40503)) >> 27;
        image::Rgb([(x / 24) as u8 ^ n as u8, (y / 16) as u8, ((x + y) / 40) as u8])
    });
    let mut jpeg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 92).encode_image(&img).unwrap();
    let mut app1 = vec![0xFF, 0xE1, 0, 34];
    app1.extend_from_slice(b"Exif\0\0MM\0\x2a\0\0\0\x08\0\x01\x01\x12\0\x03\0\0\0\x01\0\x06\0\0\0\0\0\0");
    let mut out = jpeg[..2].to_vec();
    out.extend_from_slice(&app1);
    out.extend_from_slice(&jpeg[2..]);
    std::fs::write(path, out).unwrap();
}

fn measure(path: &str, camera_w: u32, camera_h: u32) {
    let start = Instant::now();
    let photo = load_photo(path).unwrap();
    let loaded = start.elapsed();
    let pixels = photo.oriented_to(camera_w, camera_h).unwrap();
    let k = Intrinsics {
        fx: 1.1 * camera_w.max(camera_h) as f64,
        fy: 1.1 * camera_w.max(camera_h) as f64,
        cx: (camera_w as f64 - 1.0) / 2.0 + 7.3,
        cy: (camera_h as f64 - 1.0) / 2.0 - 4.1,
        skew: 0.0,
    };
    let d = Distortion { k: [-0.1, 0.02, 0.0, 0.0], d: [0.0; 3], p: [1e-3, 1e-3] };
    let out = resample(&pixels, &k, &d, 512).unwrap();
    println!(
        "camera {camera_w}x{camera_h} (EXIF orientation {}, {}): working copy {}x{} with {}x{} samples per pixel; \
         load {:.2} s, total {:.2} s; peak RSS {:.0} MB",
        photo.exif_orientation(),
        if matches!(pixels, std::borrow::Cow::Borrowed(_)) { "stored pixels" } else { "rotated copy" },
        out.image.width,
        out.image.height,
        out.samples_per_axis,
        out.samples_per_axis,
        loaded.as_secs_f64(),
        start.elapsed().as_secs_f64(),
        peak_rss_mb().unwrap_or(f64::NAN)
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() == 5 && args[1] == "measure" {
        measure(&args[2], args[3].parse().unwrap(), args[4].parse().unwrap());
        return;
    }
    let dir = std::env::temp_dir().join(format!("hairrecon-photo-memory-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("photo_6000x4000.jpg");
    write_photo(&path);
    println!("{}: {:.1} MB", path.display(), std::fs::metadata(&path).unwrap().len() as f64 / 1e6);
    let exe = std::env::current_exe().unwrap();
    for (w, h) in [(W, H), (H, W)] {
        let status = Command::new(&exe)
            .args(["measure", path.to_str().unwrap(), &w.to_string(), &h.to_string()])
            .status()
            .unwrap();
        assert!(status.success());
    }
    std::fs::remove_dir_all(dir).ok();
}
