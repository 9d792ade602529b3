//! Each reader against hand-written files whose projections are known, so that a convention error
//! made the same way in a reader and its writer (which the round trips cannot see) shows up:
//! COLMAP's half-pixel offset and quaternion order, Metashape's principal point from the image
//! centre, b1/b2 and swapped P1/P2, component and chunk transforms, NeRF's OpenGL camera axes.

use std::path::{Path, PathBuf};

use hairrecon_import::{read_colmap, read_metashape, read_nerf};

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("hairrecon-import-conv-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write(path: &Path, text: &str) {
    std::fs::write(path, text).unwrap();
}

fn close(a: [f64; 2], b: [f64; 2]) -> bool {
    (a[0] - b[0]).abs() < 1e-9 && (a[1] - b[1]).abs() < 1e-9
}

#[test]
fn colmap_text_conventions() {
    let dir = tmpdir("colmap-text");
    write(
        &dir.join("cameras.txt"),
        "# Camera list\n# comment\n1 PINHOLE 640 480 500 510 320 240\n2 SIMPLE_RADIAL 100 50 80 50 25 0.01\n",
    );
    let s = 0.5f64.sqrt();
    write(
        &dir.join("images.txt"),
        &format!(
            "# Image list\n\
             2 {s} 0 0 {s} 0 0 5 1 rot/b.jpg\n\
             10.5 20.5 -1 30 40 7\n\
             1 1 0 0 0 0 0 5 1 imgs/a.jpg\n\
             \n\
             3 1 0 0 0 0 0 1 2 c.jpg\n\
             \n"
        ),
    );
    write(&dir.join("points3D.txt"), "# points\n7 0.1 0.2 0.3 255 0 0 0.5 1 0 2 3\n9 -1 -2 -3 0 0 0 0.1\n");
    let scene = read_colmap(&dir).unwrap();
    // Sorted by image id.
    let names: Vec<&str> = scene.views.iter().map(|v| v.name.as_str()).collect();
    assert_eq!(names, ["a.jpg", "b.jpg", "c.jpg"]);
    assert_eq!(scene.views[0].image, PathBuf::from("imgs/a.jpg"));
    assert_eq!(scene.points, vec![[0.1, 0.2, 0.3], [-1.0, -2.0, -3.0]]);
    let a = &scene.views[0];
    assert_eq!((a.intrinsics.cx, a.intrinsics.cy), (319.5, 239.5));
    assert!(close(a.project([0.0, 0.0, 0.0]).unwrap(), [319.5, 239.5]));
    assert!(close(a.project([1.0, 0.0, 0.0]).unwrap(), [419.5, 239.5]));
    // A quarter turn about z (Hamilton, w first) takes world x to camera y.
    let b = &scene.views[1];
    assert!(close(b.project([1.0, 0.0, 0.0]).unwrap(), [319.5, 341.5]));
    let c = &scene.views[2];
    assert_eq!(c.distortion.k, [0.01, 0.0, 0.0, 0.0]);
    assert_eq!((c.intrinsics.fx, c.intrinsics.fy, c.intrinsics.cx, c.intrinsics.cy), (80.0, 80.0, 49.5, 24.5));
    assert!(a.project([0.0, 0.0, -10.0]).is_none(), "behind the camera");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A binary model written byte by byte, with 2D points and tracks to skip.
#[test]
fn colmap_binary_skips_points2d_and_tracks() {
    let dir = tmpdir("colmap-bin");
    let mut b = Vec::new();
    b.extend(1u64.to_le_bytes());
    b.extend(4u32.to_le_bytes());
    b.extend(3i32.to_le_bytes()); // RADIAL
    b.extend(100u64.to_le_bytes());
    b.extend(60u64.to_le_bytes());
    for p in [90.0f64, 50.0, 30.0, -0.02, 0.003] {
        b.extend(p.to_le_bytes());
    }
    write_bytes(&dir.join("cameras.bin"), &b);
    let mut b = Vec::new();
    b.extend(2u64.to_le_bytes());
    for (id, name, npts) in [(5u32, "x/first.png", 2u64), (3, "second.png", 0)] {
        b.extend(id.to_le_bytes());
        for v in [1.0f64, 0.0, 0.0, 0.0, 0.5, -0.5, 4.0] {
            b.extend(v.to_le_bytes());
        }
        b.extend(4u32.to_le_bytes());
        b.extend(name.as_bytes());
        b.push(0);
        b.extend(npts.to_le_bytes());
        for k in 0..npts {
            b.extend((k as f64).to_le_bytes());
            b.extend(2.0f64.to_le_bytes());
            b.extend((-1i64).to_le_bytes());
        }
    }
    write_bytes(&dir.join("images.bin"), &b);
    let mut b = Vec::new();
    b.extend(2u64.to_le_bytes());
    for (id, xyz, track) in [(11u64, [1.0f64, 2.0, 3.0], 2u64), (12, [4.0, 5.0, 6.0], 1)] {
        b.extend(id.to_le_bytes());
        for v in xyz {
            b.extend(v.to_le_bytes());
        }
        b.extend([1u8, 2, 3]);
        b.extend(0.25f64.to_le_bytes());
        b.extend(track.to_le_bytes());
        for k in 0..track {
            b.extend(5u32.to_le_bytes());
            b.extend((k as u32).to_le_bytes());
        }
    }
    write_bytes(&dir.join("points3D.bin"), &b);
    // A stale text export beside it: the binary model wins.
    write(&dir.join("cameras.txt"), "1 OPENCV_FISHEYE 1 1 1 1 1 1 0 0 0 0\n");
    write(&dir.join("images.txt"), "");
    let scene = read_colmap(&dir).unwrap();
    assert_eq!(scene.views.len(), 2);
    assert_eq!(scene.views[0].name, "second.png");
    assert_eq!(scene.views[1].image, PathBuf::from("x/first.png"));
    assert_eq!(scene.points, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
    let v = &scene.views[0];
    assert_eq!(v.distortion.k, [-0.02, 0.003, 0.0, 0.0]);
    assert_eq!((v.intrinsics.cx, v.intrinsics.cy), (49.5, 29.5));
    assert_eq!(v.t, [0.5, -0.5, 4.0]);
    std::fs::remove_dir_all(&dir).unwrap();
}

fn write_bytes(path: &Path, b: &[u8]) {
    std::fs::write(path, b).unwrap();
}

const METASHAPE: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<document version="1.5.0">
  <chunk label="Chunk 1" enabled="true">
    <sensors next_id="2">
      <sensor id="0" label="Canon (50mm)" type="frame">
        <resolution width="6000" height="4000"/>
        <property name="pixel_width" value="0.0039"/>
        <calibration type="frame" class="initial"><resolution width="6000" height="4000"/><f>12000</f></calibration>
        <calibration type="frame" class="adjusted">
          <resolution width="6000" height="4000"/>
          <f>12800.5</f><cx>12.25</cx><cy>-8.5</cy><b1>3.5</b1><b2>-1.25</b2>
          <k1>-0.05</k1><k2>0.1</k2><k3>0.01</k3><p1>0.0004</p1><p2>-0.0002</p2>
        </calibration>
        <covariance><params>f cx cy</params><coeffs>1 0 0 0 1 0 0 0 1</coeffs></covariance>
      </sensor>
      <sensor id="1" label="GoPro" type="fisheye">
        <resolution width="100" height="100"/>
        <calibration type="fisheye" class="adjusted"><resolution width="100" height="100"/><f>50</f></calibration>
      </sensor>
    </sensors>
    <components next_id="1" active_id="0">
      <component id="0" label="Component 1">
        <transform>
          <rotation locked="false">0 -1 0 1 0 0 0 0 1</rotation>
          <translation locked="false">1 2 3</translation>
          <scale locked="true">2</scale>
        </transform>
        <partition><camera_ids>0 1</camera_ids></partition>
      </component>
    </components>
    <cameras next_id="3" next_group_id="1">
      <group id="0" label="Folder 1" type="folder">
        <camera id="0" sensor_id="0" component_id="0" label="IMG_0001.JPG">
          <transform>1 0 0 0 0 1 0 0 0 0 1 -5 0 0 0 1</transform>
          <reference x="1" y="2" z="3" enabled="true"/>
        </camera>
      </group>
      <camera id="1" sensor_id="0" component_id="0" label="IMG_0002.JPG"/>
      <camera id="5" sensor_id="0" component_id="0" master_id="0" label="IMG_0001_right.JPG"/>
      CAMERA3
    </cameras>
    <transform>
      <rotation>1 0 0 0 1 0 0 0 1</rotation>
      <translation>10 0 0</translation>
      <scale>0.5</scale>
    </transform>
    <reference>LOCAL_CS["Local Coordinates (m)",LOCAL_DATUM["Local Datum",0],UNIT["metre",1]]</reference>
  </chunk>
</document>
"#;

#[test]
fn metashape_conventions() {
    let dir = tmpdir("metashape");
    let path = dir.join("cameras.xml");
    write(&path, &METASHAPE.replace("CAMERA3", ""));
    let scene = read_metashape(&path).unwrap();
    assert_eq!(scene.views.len(), 1);
    assert_eq!(scene.warnings.len(), 3, "{:?}", scene.warnings);
    assert!(scene.warnings.iter().any(|w| w.contains("IMG_0002.JPG") && w.contains("not aligned")));
    assert!(scene.warnings.iter().any(|w| w.contains("IMG_0001_right.JPG") && w.contains("rig")));
    let v = &scene.views[0];
    assert_eq!(v.name, "IMG_0001.JPG");
    let k = &v.intrinsics;
    assert_eq!((k.fx, k.fy, k.skew, k.cx, k.cy), (12804.0, 12800.5, -1.25, 3011.75, 1991.0));
    assert_eq!(v.distortion.p, [-0.0002, 0.0004], "Metashape's P1, P2 are OpenCV's p2, p1");
    assert_eq!(v.distortion.k, [-0.05, 0.1, 0.01, 0.0]);
    // Camera centre (0, 0, -5) in the component; component: rotate a quarter turn about z, scale 2,
    // add (1, 2, 3) -> (1, 2, -7); chunk: scale 0.5, add (10, 0, 0) -> (10.5, 1, -3.5).
    let c = hairrecon_import::pose::centre(&v.r, &v.t);
    assert!((0..3).all(|i| (c[i] - [10.5, 1.0, -3.5][i]).abs() < 1e-12), "{c:?}");
    // The camera looks along the rotated z axis (unchanged by a turn about z).
    let on_axis = v.project([10.5, 1.0, 0.0]).unwrap();
    assert!(close(on_axis, [k.cx, k.cy]), "{on_axis:?}");

    // A point off the axis, projected with Metashape's own formula (manual, appendix "Camera
    // models"), in Metashape pixel coordinates, then moved by half a pixel.
    let (x, y) = (0.03, -0.02);
    let world = {
        // Camera axes in the world: R's rows. X = C + Z (x e_x + y e_y + e_z), Z = 3.
        let r = &v.r;
        [0, 1, 2].map(|i| c[i] + 3.0 * (x * r[0][i] + y * r[1][i] + r[2][i]))
    };
    let (k1, k2, k3, p1, p2) = (-0.05, 0.1, 0.01, 0.0004, -0.0002);
    let (f, cx, cy, b1, b2) = (12800.5, 12.25, -8.5, 3.5, -1.25);
    let r2: f64 = x * x + y * y;
    let radial = 1.0 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2;
    let xd = x * radial + p1 * (r2 + 2.0 * x * x) + 2.0 * p2 * x * y;
    let yd = y * radial + p2 * (r2 + 2.0 * y * y) + 2.0 * p1 * x * y;
    let u = 3000.0 + cx + xd * f + xd * b1 + yd * b2;
    let w = 2000.0 + cy + yd * f;
    let got = v.project(world).unwrap();
    assert!((got[0] - (u - 0.5)).abs() < 1e-6 && (got[1] - (w - 0.5)).abs() < 1e-6, "{got:?} vs {u} {w}");

    // A camera on the fisheye sensor is refused, naming the file and the sensor type.
    let fisheye = r#"<camera id="2" sensor_id="1" label="fish.jpg"><transform>1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1</transform></camera>"#;
    write(&path, &METASHAPE.replace("CAMERA3", fisheye));
    let e = read_metashape(&path).unwrap_err();
    assert!(matches!(e, hairrecon_import::ImportError::UnsupportedModel { .. }), "{e}");
    assert!(e.to_string().contains("cameras.xml") && e.to_string().contains("fisheye"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn nerf_conventions() {
    let dir = tmpdir("nerf");
    let path = dir.join("transforms.json");
    write(
        &path,
        r#"{
  "camera_angle_x": 0.6911112070083618,
  "w": 800, "h": 800, "aabb_scale": 16, "scale": 0.33, "offset": [0.5, 0.5, 0.5],
  "frames": [
    { "file_path": "./train/r_0", "rotation": 0.012,
      "transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]] },
    { "file_path": "./train/r_1", "fl_x": 1000, "cx": 300.5, "w": 640, "h": 480,
      "transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]] }
  ]
}"#,
    );
    let scene = read_nerf(&path).unwrap();
    let v = &scene.views[0];
    assert_eq!((v.name.as_str(), v.image.clone()), ("r_0", PathBuf::from("./train/r_0")));
    let f = 400.0 / (0.5f64 * 0.6911112070083618).tan();
    assert!((v.intrinsics.fx - f).abs() < 1e-9 && (v.intrinsics.fy - f).abs() < 1e-9);
    assert_eq!((v.intrinsics.cx, v.intrinsics.cy), (399.5, 399.5));
    // The OpenGL camera at (0, 0, 4) looks down -z: the origin is straight ahead, world x is to
    // the right and world y (up) is up in the image (smaller v).
    assert!(close(v.project([0.0, 0.0, 0.0]).unwrap(), [399.5, 399.5]));
    let px = v.project([1.0, 0.0, 0.0]).unwrap();
    assert!((px[0] - (399.5 + f / 4.0)).abs() < 1e-9 && (px[1] - 399.5).abs() < 1e-9);
    assert!(v.project([0.0, 1.0, 0.0]).unwrap()[1] < 399.5);
    assert!(v.project([0.0, 0.0, 5.0]).is_none(), "behind the camera");
    // Per-frame values win.
    let w = &scene.views[1];
    assert_eq!((w.width, w.height, w.intrinsics.fx, w.intrinsics.fy), (640, 480, 1000.0, 1000.0));
    assert_eq!((w.intrinsics.cx, w.intrinsics.cy), (300.0, 239.5));
    std::fs::remove_dir_all(&dir).unwrap();
}
