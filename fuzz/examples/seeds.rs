//! Writes the seed inputs of every fuzz target (`fuzz/seeds/<target>/`): small valid files made
//! by hairrecon's own writers, from which the fuzzer mutates. Run by `scripts/fuzz.sh --seeds`.

use std::io::Cursor;
use std::path::{Path, PathBuf};

use glam::Vec3;
use hairrecon_core::formats;
use hairrecon_core::image_io::{self, GrayImage32, RgbImage32};
use hairrecon_core::{StrandSet, TriMesh};
use hairrecon_fuzz::FILE_SEPARATOR;
use hairrecon_import::colmap::{write_binary, write_text};
use hairrecon_import::metashape::write_xml;
use hairrecon_import::nerf::write_transforms;
use hairrecon_import::{Distortion, Intrinsics, Scene, SceneView, Units};

fn strands() -> StrandSet {
    let mut points = Vec::new();
    for s in 0..3 {
        for i in 0..4 {
            points.push(Vec3::new(s as f32 * 0.01, 0.1, 0.2 - i as f32 * 0.005));
        }
    }
    StrandSet::new(points, vec![4, 4, 4]).unwrap()
}

fn mesh() -> TriMesh {
    let v = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
    TriMesh::new(v, vec![[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]], None, None).unwrap()
}

fn scene(distortion: Distortion) -> Scene {
    let view = |i: usize| SceneView {
        name: format!("v{i}.jpg"),
        image: PathBuf::from(format!("v{i}.jpg")),
        width: 64,
        height: 48,
        intrinsics: Intrinsics { fx: 50.0, fy: 52.0, cx: 31.5, cy: 23.5, skew: 0.0 },
        distortion,
        r: [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
        t: [i as f64 * 0.1, 0.0, 3.0],
    };
    Scene { views: vec![view(0), view(1)], points: vec![[0.0, 0.1, 0.2]; 3], units: Units::Unknown, warnings: vec![] }
}

fn encoded(img: image::DynamicImage, format: image::ImageFormat) -> Vec<u8> {
    let mut out = Cursor::new(Vec::new());
    img.write_to(&mut out, format).unwrap();
    out.into_inner()
}

fn joined(dir: &Path, names: [&str; 3]) -> Vec<u8> {
    let mut out = Vec::new();
    for (i, n) in names.iter().enumerate() {
        if i > 0 {
            out.extend_from_slice(FILE_SEPARATOR);
        }
        out.extend(std::fs::read(dir.join(n)).unwrap());
    }
    out
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("seeds");
    let tmp = std::env::temp_dir().join(format!("hairrecon-fuzz-seeds-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    let mut seeds: Vec<(&str, &str, Vec<u8>)> = Vec::new();

    let s = strands();
    seeds.push(("hair", "strands.hair", formats::write_hair_strands_bytes(&s).unwrap()));
    seeds.push(("data", "strands.data", formats::write_usc_bytes(&s)));
    seeds.push(("ply", "mesh.ply", formats::write_ply_mesh_bytes(&mesh())));
    seeds.push(("ply", "strands.ply", formats::write_ply_strands_bytes(&s)));
    let mut with_quality = Vec::new();
    formats::ply::write_ply_mesh_with_quality(&mut with_quality, &mesh(), Some(&[0.1, 0.2, 0.3, 0.4])).unwrap();
    seeds.push(("ply", "quality.ply", with_quality));
    seeds.push(("obj", "mesh.obj", formats::write_obj_bytes(&mesh())));
    seeds.push(("obj", "lines.obj", formats::write_obj_lines_bytes(&s)));

    let rgb = image::RgbImage::from_fn(12, 8, |x, y| image::Rgb([(x * 20) as u8, (y * 30) as u8, 90]));
    let gray = image::GrayImage::from_fn(12, 8, |x, y| image::Luma([(x * y * 3) as u8]));
    let gray16 = image::ImageBuffer::<image::Luma<u16>, _>::from_fn(12, 8, |x, y| image::Luma([(x * 4000 + y) as u16]));
    for target in ["image", "photo"] {
        seeds.push((target, "rgb.png", encoded(rgb.clone().into(), image::ImageFormat::Png)));
        seeds.push((target, "gray.png", encoded(gray.clone().into(), image::ImageFormat::Png)));
        seeds.push((target, "gray16.png", encoded(gray16.clone().into(), image::ImageFormat::Png)));
        seeds.push((target, "rgb.jpg", encoded(rgb.clone().into(), image::ImageFormat::Jpeg)));
        seeds.push((target, "rgb.tif", encoded(rgb.clone().into(), image::ImageFormat::Tiff)));
    }
    let exr_gray = GrayImage32::new(6, 4, (0..24).map(|i| i as f32 * 0.25).collect()).unwrap();
    image_io::write_exr_gray_f32(tmp.join("gray.exr"), &exr_gray).unwrap();
    let exr_rgb = RgbImage32::new(6, 4, (0..72).map(|i| i as f32 * 0.1).collect()).unwrap();
    image_io::write_exr_rgb_f32(tmp.join("rgb.exr"), &exr_rgb).unwrap();
    for n in ["gray.exr", "rgb.exr"] {
        seeds.push(("image", n, std::fs::read(tmp.join(n)).unwrap()));
    }

    // A capture whose files are absent (the reader checks them after the JSON), and one with masks.
    let capture = r#"{
  "version": 1, "units": "metres", "frame": "canonical", "convention": "opencv",
  "views": [
    { "name": "view_000", "image": "images/view_000.png", "mask": "masks/view_000.png", "width": 64, "height": 48,
      "K": [[50, 0, 31.5], [0, 50, 23.5], [0, 0, 1]], "R": [[1, 0, 0], [0, 0, -1], [0, 1, 0]], "t": [0, 0.1, 0.6] },
    { "name": "view_001", "image": "images/view_001.png", "width": 64, "height": 48,
      "K": [[50, 0, 31.5], [0, 50, 23.5], [0, 0, 1]], "R": [[0, 1, 0], [0, 0, -1], [-1, 0, 0]], "t": [0, 0.1, 0.6] }
  ],
  "raw_mesh": "raw_mesh.ply", "head_mesh": "head.ply", "scalp_mesh": "scalp.ply", "gt_strands": "gt/strands.hair"
}"#;
    seeds.push(("capture_json", "capture.json", capture.as_bytes().to_vec()));
    let imported = capture.replace("\"metres\"", "\"unknown\"").replace("\"canonical\"", "\"imported\"");
    seeds.push(("capture_json", "imported.json", imported.into_bytes()));

    let brown = Distortion { k: [0.01, -0.002, 0.0, 0.0], d: [0.0; 3], p: [0.0005, -0.0003] };
    for (name, d) in [("pinhole", Distortion::default()), ("opencv", brown)] {
        let dir = tmp.join(format!("text-{name}"));
        write_text(&dir, &scene(d)).unwrap();
        seeds.push(("colmap_text", name, joined(&dir, ["cameras.txt", "images.txt", "points3D.txt"])));
        let dir = tmp.join(format!("bin-{name}"));
        write_binary(&dir, &scene(d)).unwrap();
        seeds.push(("colmap_binary", name, joined(&dir, ["cameras.bin", "images.bin", "points3D.bin"])));
        write_xml(&tmp.join("cameras.xml"), &scene(d)).unwrap();
        seeds.push(("metashape", name, std::fs::read(tmp.join("cameras.xml")).unwrap()));
        write_transforms(&tmp.join("transforms.json"), &scene(d)).unwrap();
        seeds.push(("nerf", name, std::fs::read(tmp.join("transforms.json")).unwrap()));
    }

    for (target, name, bytes) in &seeds {
        let dir = root.join(target);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join(name), bytes).unwrap();
    }
    std::fs::remove_dir_all(&tmp).unwrap();
    println!("{} seeds in {}", seeds.len(), root.display());
}
