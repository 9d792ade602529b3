//! The generator on the bundled head: outside the head, rooted on the scalp, the right sizes, the
//! face free, hair with volume standing off the crown, and the same bytes for the same seed with any
//! number of threads.

use hairrecon_core::formats::read_mesh;
use hairrecon_core::layer_height::LayerHeights;
use hairrecon_core::{Bvh, StrandSet, TriMesh};
use hairrecon_synth::{fixtures_dir, HairGenerator, Style, SynthOptions};

fn fixtures() -> (TriMesh, TriMesh) {
    let dir = fixtures_dir();
    (read_mesh(dir.join("head.ply")).unwrap(), read_mesh(dir.join("scalp.ply")).unwrap())
}

fn opts(style: Style, strands: usize, seed: u64) -> SynthOptions {
    SynthOptions { strands, points: 100, seed, ..SynthOptions::new(style) }
}

/// Expected strand lengths (root to tip along the polyline), metres: (least, greatest median, most).
fn length_range(style: Style) -> (f32, f32, f32, f32) {
    match style {
        Style::Straight => (0.30, 0.40, 0.50, 0.60),
        Style::Wavy => (0.30, 0.40, 0.55, 0.65),
        // Curls make the strand about twice as long as its 0.17 m centreline.
        Style::Curly => (0.15, 0.28, 0.42, 0.50),
        Style::Short => (0.04, 0.06, 0.08, 0.10),
        Style::Bob => (0.10, 0.15, 0.19, 0.23),
        Style::Volume => (0.22, 0.27, 0.34, 0.38),
        Style::SidePart => (0.30, 0.38, 0.46, 0.60),
        // Strands from the crown are about half as long as those from the nape.
        Style::Layered => (0.10, 0.18, 0.28, 0.48),
        Style::Spiky => (0.025, 0.045, 0.07, 0.10),
        Style::Ponytail => (0.12, 0.32, 0.40, 0.52),
        // Coils of 3 mm radius and 9 mm period make a strand about 2.3 times its 0.12 m centreline.
        Style::Coils => (0.12, 0.23, 0.31, 0.36),
        Style::LooseCurls => (0.33, 0.42, 0.52, 0.62),
        // The wavy shape, a little shorter as 15-point polylines cut its bends.
        Style::Coarse => (0.30, 0.40, 0.52, 0.60),
    }
}

#[test]
fn every_style_is_outside_the_head_rooted_on_the_scalp_and_sized() {
    let (head, scalp) = fixtures();
    let gen = HairGenerator::new(&head, scalp.clone()).unwrap();
    let scalp_bvh = Bvh::new(scalp);
    for style in Style::ALL {
        let hair = gen.generate(&opts(style, 1000, 7), &|_| {}).unwrap();
        assert_eq!(hair.num_strands(), 1000);
        let points = if style == Style::Coarse { 15 } else { 100 };
        assert!(hair.counts().iter().all(|&c| c == points), "{style}: point counts");
        let mut worst = f32::INFINITY;
        let mut in_face = 0;
        for s in hair.iter() {
            let root_off = scalp_bvh.closest_point(s[0], 1.0).unwrap().distance;
            assert!(root_off < 5e-4, "{style}: root {:?} is {root_off} m off the scalp", s[0]);
            for &p in &s[1..] {
                if let Some(d) = gen.collider().signed_distance(p, 0.01) {
                    worst = worst.min(d);
                }
                // In front of the face, between the chin and the eyebrows.
                if p.y < -0.05 && p.x.abs() < 0.05 && p.z > -0.07 && p.z < 0.06 {
                    in_face += 1;
                    if in_face < 6 {
                        println!("{style}: face point {p}");
                    }
                }
            }
        }
        assert!(worst >= 0.0, "{style}: a point is {} m inside the head", -worst);
        assert_eq!(in_face, 0, "{style}: {in_face} points cover the face");
        let st = hair.length_stats().unwrap();
        let (lo, med_lo, med_hi, hi) = length_range(style);
        println!("{style}: closest point to the head {worst:.5} m; lengths {st:?}");
        assert!(st.min >= lo && st.max <= hi, "{style}: lengths {st:?} outside [{lo}, {hi}]");
        assert!(st.median >= med_lo && st.median <= med_hi, "{style}: median length {}", st.median);
    }
}

#[test]
fn long_straight_hair_falls_past_the_shoulders_and_curly_curls() {
    let (head, scalp) = fixtures();
    let gen = HairGenerator::new(&head, scalp).unwrap();
    let tip_z = |h: &StrandSet| {
        let mut z: Vec<f32> = h.iter().map(|s| s[s.len() - 1].z).collect();
        z.sort_by(f32::total_cmp);
        z[z.len() / 2]
    };
    // The shoulders of the fixture are at about z = -0.13 m (the mesh is cut at -0.168 m).
    let straight = gen.generate(&opts(Style::Straight, 500, 3), &|_| {}).unwrap();
    let z = tip_z(&straight);
    assert!(z < -0.2, "median tip height of straight hair {z}");
    // Curly: the strand is much longer than the distance from root to tip, and its tangent turns
    // a full circle many times (about 0.17 m / 0.022 m per turn = 7.7 turns).
    let curly = gen.generate(&opts(Style::Curly, 200, 3), &|_| {}).unwrap();
    let mut ratio = Vec::new();
    for (i, s) in curly.iter().enumerate() {
        ratio.push(curly.strand_length(i) / s[0].distance(s[s.len() - 1]));
    }
    ratio.sort_by(f32::total_cmp);
    assert!(ratio[ratio.len() / 2] > 2.0, "curly: median length / chord {}", ratio[ratio.len() / 2]);
    let st = straight.iter().enumerate().map(|(i, s)| straight.strand_length(i) / s[0].distance(s[99]));
    let mut st: Vec<f32> = st.collect();
    st.sort_by(f32::total_cmp);
    assert!(st[st.len() / 2] < 1.5, "straight: median length / chord {}", st[st.len() / 2]);
}

/// Over the crown, the volume style's hair stands 1–3 cm off the scalp (the median of 1 cm cells'
/// median heights); straight hair lies within a few millimetres of it.
#[test]
fn hair_with_volume_stands_off_the_crown_and_straight_hair_lies_on_it() {
    let (head, scalp) = fixtures();
    let gen = HairGenerator::new(&head, scalp.clone()).unwrap();
    let scalp = Bvh::new(scalp);
    let height = |style| {
        let hair = gen.generate(&opts(style, 3000, 5), &|_| {}).unwrap();
        LayerHeights::measure(&hair, &scalp, 0.001).unwrap().median().unwrap()
    };
    let (volume, straight) = (height(Style::Volume), height(Style::Straight));
    println!("median height over the crown: volume {:.1} mm, straight {:.1} mm", 1e3 * volume, 1e3 * straight);
    assert!((0.010..=0.030).contains(&volume), "volume: {volume} m");
    assert!(straight < 0.006, "straight: {straight} m");
}

/// The ponytail's strands pass through its tie; the layered cut's crown strands are much shorter
/// than those from the nape (the straight style's are not).
#[test]
fn a_ponytail_is_tied_and_a_layered_cut_is_shorter_at_the_crown() {
    let (head, scalp) = fixtures();
    let gen = HairGenerator::new(&head, scalp).unwrap();
    let tail = gen.generate(&opts(Style::Ponytail, 1000, 4), &|_| {}).unwrap();
    let through = tail
        .iter()
        .filter(|s| {
            s.iter().map(|p| p.distance(hairrecon_synth::style::PONYTAIL_TIE)).fold(f32::INFINITY, f32::min) < 0.02
        })
        .count();
    println!("ponytail: {through} of 1000 strands pass within 2 cm of the tie");
    assert!(through >= 950, "ponytail: only {through} of 1000 strands pass the tie");
    let ratio = |style| {
        let hair = gen.generate(&opts(style, 2000, 4), &|_| {}).unwrap();
        let median = |high: bool| {
            let mut l: Vec<f32> = (0..hair.num_strands())
                .filter(|&i| if high { hair.strand(i)[0].z > 0.14 } else { hair.strand(i)[0].z < 0.05 })
                .map(|i| hair.strand_length(i))
                .collect();
            l.sort_by(f32::total_cmp);
            l[l.len() / 2]
        };
        median(true) / median(false)
    };
    let (layered, straight) = (ratio(Style::Layered), ratio(Style::Straight));
    println!("crown / nape median length: layered {layered:.2}, straight {straight:.2}");
    assert!(layered < 0.65, "layered: crown / nape {layered}");
    assert!(straight > 0.8, "straight: crown / nape {straight}");
}

#[test]
fn same_seed_same_bytes_with_any_thread_count() {
    let (head, scalp) = fixtures();
    let gen = HairGenerator::new(&head, scalp).unwrap();
    let run = |threads: usize, seed: u64| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| gen.generate(&opts(Style::Wavy, 300, seed), &|_| {}).unwrap())
    };
    let a = run(1, 11);
    let b = run(3, 11);
    let bytes = |h: &StrandSet| h.flat_points().iter().flat_map(|f| f.to_le_bytes()).collect::<Vec<u8>>();
    assert_eq!(bytes(&a), bytes(&b));
    assert_ne!(bytes(&a), bytes(&run(2, 12)));
}

#[test]
fn bad_options_are_clear_errors() {
    let (head, scalp) = fixtures();
    let gen = HairGenerator::new(&head, scalp).unwrap();
    let e = gen.generate(&SynthOptions { points: 1, ..opts(Style::Short, 10, 1) }, &|_| {}).unwrap_err();
    assert!(e.to_string().contains("points per strand"), "{e}");
    let e = "afro".parse::<Style>().unwrap_err();
    assert!(e.to_string().contains("straight, wavy, curly, short, bob, volume, side_part"), "{e}");
    let bad = hairrecon_synth::StyleParams { layers: 1.0, ..Style::Layered.params() };
    let e = gen.generate(&SynthOptions { params: bad, ..opts(Style::Layered, 10, 1) }, &|_| {}).unwrap_err();
    assert!(e.to_string().contains("layers"), "{e}");
}
