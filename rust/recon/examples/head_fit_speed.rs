//! Times `fit_similarity` on a large raw mesh: the bundled head with every triangle split into four
//! `LEVELS` times (default 2: about 700k vertices, 1.3M triangles), moved into a similarity frame.
//!
//! ```text
//! cargo run --release -p hairrecon-recon --example head_fit_speed [LEVELS]
//! ```

use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Instant;

use glam::{DMat3, DVec3};
use hairrecon_core::formats::read_mesh;
use hairrecon_core::TriMesh;
use hairrecon_recon::head_fit::{fit_similarity, transform_mesh, FitOptions, HeadTemplate, Similarity};

/// Every triangle split into four at its edges' midpoints (shared midpoints shared).
fn subdivide(m: &TriMesh) -> TriMesh {
    let mut vertices = m.vertices.clone();
    let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
    let mut edge = |a: u32, b: u32, vertices: &mut Vec<glam::Vec3>| {
        *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
            vertices.push(0.5 * (vertices[a as usize] + vertices[b as usize]));
            vertices.len() as u32 - 1
        })
    };
    let mut triangles = Vec::with_capacity(4 * m.triangles.len());
    for &[a, b, c] in &m.triangles {
        let (ab, bc, ca) = (edge(a, b, &mut vertices), edge(b, c, &mut vertices), edge(c, a, &mut vertices));
        triangles.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
    }
    TriMesh::new(vertices, triangles, None, None).expect("valid")
}

fn main() {
    let levels: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(2);
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../blend_fixtures");
    let head = read_mesh(dir.join("head.ply")).expect("head.ply");
    let scalp = read_mesh(dir.join("scalp.ply")).expect("scalp.ply");
    let template = HeadTemplate::new(&head, Some(&scalp), 2000, 7).expect("template");
    let mut raw = TriMesh::new(head.vertices.clone(), head.triangles.clone(), None, None).expect("valid");
    for _ in 0..levels {
        raw = subdivide(&raw);
    }
    let truth = Similarity {
        scale: 3.7,
        rotation: DMat3::from_axis_angle(DVec3::new(0.3, -0.8, 0.5).normalize(), 2.2),
        translation: DVec3::new(12.0, -3.0, 40.0),
    };
    // The same with a backdrop four times the head's area 0.35 m behind it (two triangles): the
    // scale and centre priors are wrong, so the fallback search runs.
    let mut with_backdrop = raw.clone();
    let b = with_backdrop.vertices.len() as u32;
    with_backdrop.vertices.extend([
        glam::Vec3::new(-0.45, 0.35, -0.6),
        glam::Vec3::new(0.45, 0.35, -0.6),
        glam::Vec3::new(0.45, 0.35, 0.3),
        glam::Vec3::new(-0.45, 0.35, 0.3),
    ]);
    with_backdrop.triangles.extend([[b, b + 1, b + 2], [b, b + 2, b + 3]]);
    for (what, raw) in [("head", raw), ("head and backdrop", with_backdrop)] {
        run(what, &transform_mesh(&raw, &truth), &template, &truth);
    }
}

fn run(what: &str, raw: &TriMesh, template: &HeadTemplate, truth: &Similarity) {
    println!(
        "{what}: {} vertices, {} triangles; {} threads",
        raw.vertices.len(),
        raw.triangles.len(),
        rayon::current_num_threads()
    );
    let t0 = Instant::now();
    let fit = fit_similarity(template, raw, None, &FitOptions::default()).expect("fit");
    let secs = t0.elapsed().as_secs_f64();
    let want = truth.inverse();
    println!(
        "  fit in {secs:.2} s: residual {:.3} mm, rotation error {:.3}°, scale error {:.3}%, exposed {:.1}%",
        fit.residual_mm,
        want.rotation_angle_to(&fit.to_canonical),
        (fit.to_canonical.scale / want.scale - 1.0).abs() * 100.0,
        fit.score.outside * 100.0
    );
}
