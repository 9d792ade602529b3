//! Inputs for measuring an import of full-size photos: six 6000x4000 JPEGs of a textured pattern, a
//! COLMAP text model of six OPENCV cameras (k1 = -0.1, k2 = 0.02, p1 = p2 = 1e-3) in an arbitrary
//! frame, and a small mesh.
//!
//! ```text
//! cargo run -p hairrecon-import --release --example large_photos -- /tmp/large
//! /usr/bin/time -v target/release/hairrecon import colmap /tmp/large/sparse --images /tmp/large/images \
//!     --mesh /tmp/large/mesh.ply --out /tmp/large/capture
//! ```
//!
//! The second command's "Maximum resident set size" is the import's peak memory.

use std::path::PathBuf;

use hairrecon_import::{colmap, pose, Distortion, Intrinsics, Scene, SceneView, Units};

const W: u32 = 6000;
const H: u32 = 4000;

fn main() {
    let dir = PathBuf::from(std::env::args().nth(1).expect("usage: large_photos OUT_DIR"));
    let images = dir.join("images");
    std::fs::create_dir_all(&images).unwrap();
    let img = image::RgbImage::from_fn(W, H, |x, y| {
        let n = (x.wrapping_mul(2654435761) ^ y.wrapping_mul(40503)) >> 27;
        image::Rgb([(x / 24) as u8 ^ n as u8, (y / 16) as u8, ((x + y) / 40) as u8])
    });
    let distortion = Distortion { k: [-0.1, 0.02, 0.0, 0.0], d: [0.0; 3], p: [1e-3, 1e-3] };
    let mut views = Vec::new();
    for i in 0..6 {
        let name = format!("DSC_{i:04}.JPG");
        image::codecs::jpeg::JpegEncoder::new_with_quality(std::fs::File::create(images.join(&name)).unwrap(), 92)
            .encode_image(&img)
            .unwrap();
        let a = i as f64 * std::f64::consts::TAU / 6.0;
        let c = [30.0 * a.cos() + 5.0, 30.0 * a.sin() - 2.0, 7.0];
        let z = [-a.cos(), -a.sin(), 0.0];
        let x = [-z[1], z[0], 0.0];
        let r = [x, [0.0, 0.0, -1.0], z];
        views.push(SceneView {
            name: name.clone(),
            image: name.into(),
            width: W,
            height: H,
            intrinsics: Intrinsics { fx: 6600.0, fy: 6600.0, cx: 3001.5, cy: 1996.2, skew: 0.0 },
            distortion,
            r,
            t: pose::translation(&r, &c),
        });
    }
    let sparse = dir.join("sparse");
    std::fs::create_dir_all(&sparse).unwrap();
    let scene = Scene { views, points: Vec::new(), units: Units::Unknown, warnings: Vec::new() };
    colmap::write_text(&sparse, &scene).unwrap();
    let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
               element face 1\nproperty list uchar int vertex_indices\nend_header\n5 -2 6\n6 -2 7\n5 -1 7\n3 0 1 2\n";
    std::fs::write(dir.join("mesh.ply"), ply).unwrap();
    println!("{}", dir.display());
}
