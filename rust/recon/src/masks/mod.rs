//! Hair masks without ground truth, as the paper makes them and without a hair prior:
//!
//! 1. **Hair region of the raw mesh** ([`region`]): per vertex, the probability of hair from
//!    where it lies against the fitted head and from its colour in the views that see it
//!    ([`render::seen`]: in front of the camera, facing it, not hidden by the raw mesh), against
//!    colour models learned from the capture itself ([`colour`]).
//! 2. **Its silhouette in each view** ([`render`]): one ray per pixel against the raw mesh and the
//!    fitted head; a pixel takes the region's probability where its ray meets the raw mesh. Near
//!    the silhouette, a pixel outside the hair takes the hair's share of its colour, read as a
//!    blend of the hair's and what lies behind it ([`beyond`]: hair the raw mesh left out).
//! 3. **Alpha** ([`trimap`], [`matting`]): a trimap of that silhouette, its band as wide as a few
//!    millimetres are at the head's distance, and closed-form matting against the photo inside the
//!    band, with the silhouette as a weak prior.
//!
//! [`quality`] scores masks against a synthetic capture's own; [`capture_masks`] writes them into
//! a capture (`masks/`, `hair_region.ply`), keeping masks a user gave.

pub mod beyond;
pub mod capture_masks;
pub mod colour;
pub mod matting;
pub mod quality;
pub mod region;
pub mod render;
pub mod trimap;

use glam::{Vec2, Vec3};
use hairrecon_core::capture::Capture;
use hairrecon_core::image_io::{read_rgb_f32, GrayImage32, RgbImage32};
use hairrecon_core::{Bvh, FormatError};
use rayon::prelude::*;
use thiserror::Error;

use crate::progress::{Cancelled, Progress};
use beyond::BeyondOptions;
use matting::{closed_form_matting, MattingError, MattingOptions};
use region::{RegionOptions, RegionSummary};
use render::{PixelHit, Surface, ViewHits};
use trimap::Trimap;

/// The parameters of the masks.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MaskOptions {
    pub region: RegionOptions,
    /// Hair beyond the raw mesh ([`beyond`]); a configuration without it replays without it.
    #[serde(default = "BeyondOptions::off")]
    pub beyond: BeyondOptions,
    /// Weight of each pixel's own colour (its hair-against-rest log-likelihood ratio under the
    /// region's colour models) added to the region's log-odds; 0 renders the region alone.
    pub pixel_colour: f32,
    /// Where a ray passes through a hole of the raw mesh and meets the fitted head's scalp, the
    /// pixel takes the region's probability at the raw mesh's point closest to the scalp's, when it
    /// lies within this distance (mm; 0: the head's pixels are never hair). A configuration without
    /// it replays without it.
    #[serde(default)]
    pub hole_mm: f32,
    /// Depth slack (mm) of a vertex's visibility test, beyond one and a half pixels' footprint.
    pub visibility_mm: f32,
    /// Half-width (mm, at the head's distance) of the trimap's unknown band around the silhouette.
    pub band_mm: f32,
    /// The unknown band is at least this many pixels wide on each side.
    pub min_band_px: f32,
    /// Closed-form matting inside the band; `false` keeps the silhouette's hard edge.
    pub matting: bool,
    /// Matting's regulariser (colours in [0, 1]).
    pub matting_epsilon: f32,
    /// Weight of the silhouette as a prior of alpha inside the band.
    pub matting_prior: f32,
}

impl Default for MaskOptions {
    fn default() -> Self {
        Self {
            region: RegionOptions::default(),
            beyond: BeyondOptions::default(),
            pixel_colour: 0.5,
            hole_mm: 50.0,
            visibility_mm: 3.0,
            band_mm: 12.0,
            min_band_px: 2.0,
            matting: true,
            matting_epsilon: MattingOptions::default().epsilon,
            matting_prior: MattingOptions::default().prior_weight,
        }
    }
}

/// Why masks could not be made.
#[derive(Debug, Error)]
pub enum MaskError {
    #[error(transparent)]
    Cancelled(#[from] Cancelled),
    #[error(transparent)]
    Format(#[from] FormatError),
    #[error(
        "{dir}: the capture has no head mesh; masks need the fitted head to tell skin from hair. Run `hairrecon \
         fit-head {dir} --write` first (or give head_mesh and scalp_mesh in capture.json)"
    )]
    NoHead { dir: String },
    #[error("view {view}: the image {path} is {found} but the view says {expected}")]
    ImageSize { view: String, path: String, found: String, expected: String },
    #[error("view {view}: matting failed: {source}")]
    Matting { view: String, source: MattingError },
}

/// Masks of every view and the region they came from.
#[derive(Debug, Clone)]
pub struct MaskSet {
    /// Hair probability of each raw-mesh vertex.
    pub region: Vec<f32>,
    /// Alpha of each view, in the capture's order.
    pub alphas: Vec<GrayImage32>,
    pub summary: RegionSummary,
    /// Where the time went.
    pub seconds: MaskTimes,
}

/// Wall-clock seconds of each phase of [`make_masks`].
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct MaskTimes {
    /// Reading the meshes and the photos, and one ray per pixel of every view.
    pub rays: f64,
    /// The raw mesh's colours and the hair region.
    pub region: f64,
    /// The silhouettes and the hair beyond the raw mesh.
    pub silhouettes: f64,
    /// The trimaps and matting (or the silhouettes' thresholds without matting).
    pub matting: f64,
}

/// Makes masks for every view of `capture` (in the canonical frame, with a head and a scalp).
pub fn make_masks(capture: &Capture, opts: &MaskOptions, progress: &dyn Progress) -> Result<MaskSet, MaskError> {
    const STAGE: &str = "masks";
    let dir = capture.dir.display().to_string();
    let (Some(head_path), Some(scalp_path)) = (&capture.head_mesh, &capture.scalp_mesh) else {
        return Err(MaskError::NoHead { dir });
    };
    let mut seconds = MaskTimes::default();
    let mut clock = std::time::Instant::now();
    let mut lap = |total: &mut f64| {
        *total += clock.elapsed().as_secs_f64();
        clock = std::time::Instant::now();
    };
    progress.update(STAGE, 0.0, "reading the meshes");
    let raw = capture.read_mesh(&capture.raw_mesh)?;
    let head = Bvh::new(capture.read_mesh(head_path)?);
    let scalp = Bvh::new(capture.read_mesh(scalp_path)?);
    let normals = raw.compute_vertex_normals();
    let raw_bvh = Bvh::new(raw);
    let raw = raw_bvh.mesh();
    progress.check()?;

    let n_views = capture.views.len();
    let mut images = Vec::with_capacity(n_views);
    let mut hits = Vec::with_capacity(n_views);
    for (k, view) in capture.views.iter().enumerate() {
        progress.update(STAGE, 0.4 * k as f32 / n_views as f32, &format!("view {}: what each pixel sees", view.name));
        let image = read_rgb_f32(&view.image)?;
        let (w, h) = (view.camera.width(), view.camera.height());
        if (image.width, image.height) != (w, h) {
            return Err(MaskError::ImageSize {
                view: view.name.clone(),
                path: view.image.display().to_string(),
                found: format!("{}x{}", image.width, image.height),
                expected: format!("{w}x{h}"),
            });
        }
        images.push(image);
        hits.push(ViewHits::cast(&view.camera, &raw_bvh, Some(&head)));
        progress.check()?;
    }

    lap(&mut seconds.rays);
    progress.update(STAGE, 0.4, "the raw mesh's colours");
    let tol = opts.visibility_mm * 1e-3;
    // Per vertex, its mean colour over the views that see it: L*a*b* for the colour models,
    // linear RGB for the blends of hair and what lies behind it; and how much the views disagree
    // on it (the RMS distance from that mean), which tells a sheet of sparse hair (`beyond`).
    let per_vertex: Vec<(Option<Vec3>, Option<Vec3>, f32)> = raw
        .vertices
        .par_iter()
        .zip(normals.par_iter())
        .map(|(&p, &n)| {
            let (mut lab, mut rgb, mut rgb2, mut weight) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, 0.0f32);
            for (k, view) in capture.views.iter().enumerate() {
                if let Some((pixel, facing)) = render::seen(&view.camera, &hits[k], p, n, tol) {
                    let c = colour::srgb_to_linear(bilinear(&images[k], pixel));
                    lab += facing * colour::linear_to_lab(c);
                    rgb += facing * c;
                    rgb2 += facing * c * c;
                    weight += facing;
                }
            }
            if weight > 0.0 {
                let mean = rgb / weight;
                let spread = (rgb2 / weight - mean * mean).max(Vec3::ZERO).element_sum().sqrt();
                (Some(lab / weight), Some(mean), spread)
            } else {
                (None, None, 0.0)
            }
        })
        .collect();
    let colours: Vec<Option<Vec3>> = per_vertex.iter().map(|v| v.0).collect();
    let linear: Vec<Option<Vec3>> = per_vertex.iter().map(|v| v.1).collect();
    let spread: Vec<f32> = per_vertex.iter().map(|v| v.2).collect();
    drop(per_vertex);
    progress.check()?;

    progress.update(STAGE, 0.5, "the hair region");
    let (prior, far) = region::geometry_prior(raw, &head, &scalp, &opts.region);
    let neighbours = region::vertex_neighbours(raw);
    let (prob, models, summary) = region::hair_probability(&prior, &colours, &neighbours, &opts.region);
    progress.check()?;
    lap(&mut seconds.region);

    let matting_opts =
        MattingOptions { epsilon: opts.matting_epsilon, prior_weight: opts.matting_prior, ..MattingOptions::default() };
    let centre = raw_bvh.mesh().bbox();
    let centre = (centre.0 + centre.1) * 0.5;
    let behind = beyond::Behind { raw, colours: &linear, spread: &spread, far: &far };
    let surfaces = Surfaces { raw: &raw_bvh, head: &head, scalp: &scalp, hole: opts.hole_mm * 1e-3 };
    let mut alphas = Vec::with_capacity(n_views);
    for (k, view) in capture.views.iter().enumerate() {
        progress.update(STAGE, 0.55 + 0.45 * k as f32 / n_views as f32, &format!("view {}: alpha", view.name));
        let mut silhouette = silhouette(&hits[k], &surfaces, &prob, &images[k], models.as_ref(), opts.pixel_colour);
        // Pixels per millimetre at the head's distance.
        let px_per_mm = 1e-3 * view.camera.k().col(0).x / view.camera.project(centre).map_or(1.0, |p| p.depth);
        beyond::extend(
            &mut silhouette.data,
            &hits[k],
            &images[k],
            &behind,
            opts.beyond.reach_mm * px_per_mm,
            &opts.beyond,
        );
        lap(&mut seconds.silhouettes);
        let alpha = if opts.matting {
            let band = (opts.band_mm * px_per_mm).max(opts.min_band_px);
            let trimap = Trimap::from_probability(&silhouette.data, silhouette.width, silhouette.height, band);
            let data = closed_form_matting(&images[k], &trimap, Some(&silhouette.data), &matting_opts)
                .map_err(|source| MaskError::Matting { view: view.name.clone(), source })?;
            GrayImage32 { width: silhouette.width, height: silhouette.height, data }
        } else {
            let data = silhouette.data.iter().map(|&p| if p >= 0.5 { 1.0 } else { 0.0 }).collect();
            GrayImage32 { width: silhouette.width, height: silhouette.height, data }
        };
        alphas.push(alpha);
        lap(&mut seconds.matting);
        progress.check()?;
    }
    progress.update(STAGE, 1.0, "done");
    Ok(MaskSet { region: prob, alphas, summary, seconds })
}

/// A point of the fitted head this close (metres) to its scalp is on the scalp.
const ON_SCALP: f32 = 0.002;

/// The surfaces a view's rays met.
struct Surfaces<'a> {
    raw: &'a Bvh,
    head: &'a Bvh,
    scalp: &'a Bvh,
    /// [`MaskOptions::hole_mm`] in metres.
    hole: f32,
}

impl Surfaces<'_> {
    /// The region's probability where the ray of `h` met the raw mesh, or through a hole of the raw
    /// mesh the fitted head's scalp: the probability of the raw mesh's closest point within `hole`
    /// (a hole in the hair over the scalp shows the hair around it). `None` elsewhere: the face,
    /// ears and neck of the head, where it lies in front of the raw mesh, are not hair (a shaded
    /// neck the raw mesh missed would otherwise take the hair behind it).
    fn region(&self, h: &PixelHit, prob: &[f32]) -> Option<f32> {
        let bary = Vec3::new(1.0 - h.u - h.v, h.u, h.v);
        match h.surface {
            Surface::Raw => Some(self.raw.interpolate(prob, h.triangle, bary)),
            Surface::Head if self.hole > 0.0 => {
                let p = self.head.interpolate(&self.head.mesh().vertices, h.triangle, bary);
                self.scalp.closest_point(p, ON_SCALP)?;
                self.raw.closest_point(p, self.hole).map(|c| self.raw.interpolate(prob, c.triangle, c.bary))
            }
            _ => None,
        }
    }
}

/// The region's probability where each pixel's ray meets the raw mesh (or the head through one of
/// its holes; 0 where it meets the head elsewhere or nothing), with the pixel's own colour.
fn silhouette(
    hits: &ViewHits,
    surfaces: &Surfaces,
    prob: &[f32],
    image: &RgbImage32,
    models: Option<&region::ColourModels>,
    colour_weight: f32,
) -> GrayImage32 {
    let data = hits
        .hits
        .par_iter()
        .enumerate()
        .map(|(i, h)| match surfaces.region(h, prob) {
            Some(p) => match models {
                Some(m) if colour_weight > 0.0 => {
                    let c = &image.data[3 * i..3 * i + 3];
                    let l = m.log_ratio(colour::srgb_to_lab([c[0], c[1], c[2]]));
                    let p = p.clamp(1e-4, 1.0 - 1e-4);
                    1.0 / (1.0 + (-((p / (1.0 - p)).ln() + colour_weight * l)).exp())
                }
                _ => p,
            },
            None => 0.0,
        })
        .collect();
    GrayImage32 { width: hits.width, height: hits.height, data }
}

/// The image's colour at a sub-pixel position (pixel centres at integers), clamped at the borders.
fn bilinear(img: &RgbImage32, p: Vec2) -> [f32; 3] {
    let (w, h) = (img.width as i64, img.height as i64);
    let x0 = p.x.floor();
    let y0 = p.y.floor();
    let (fx, fy) = (p.x - x0, p.y - y0);
    let at = |x: i64, y: i64| img.get(x.clamp(0, w - 1) as u32, y.clamp(0, h - 1) as u32);
    let (x0, y0) = (x0 as i64, y0 as i64);
    let (a, b, c, d) = (at(x0, y0), at(x0 + 1, y0), at(x0, y0 + 1), at(x0 + 1, y0 + 1));
    let mut out = [0.0; 3];
    for i in 0..3 {
        out[i] = (a[i] * (1.0 - fx) + b[i] * fx) * (1.0 - fy) + (c[i] * (1.0 - fx) + d[i] * fx) * fy;
    }
    out
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    #[test]
    fn options_written_before_the_hair_beyond_the_mesh_and_the_hole_fill_replay_without_them() {
        let mut old = serde_json::to_value(MaskOptions::default()).unwrap();
        old.as_object_mut().unwrap().remove("beyond");
        old.as_object_mut().unwrap().remove("hole_mm");
        let back: MaskOptions = serde_json::from_value(old.clone()).unwrap();
        assert_eq!(back.beyond.reach_mm, 0.0);
        assert_eq!(back.hole_mm, 0.0);
        // A beyond written before the loose sheets replays without them.
        old["beyond"] = serde_json::json!({"reach_mm": 30.0});
        let back: MaskOptions = serde_json::from_value(old).unwrap();
        assert_eq!(back.beyond.reach_mm, 30.0);
        assert!(!back.beyond.loose_sheets && BeyondOptions::default().loose_sheets);
        assert!(MaskOptions::default().beyond.reach_mm > 0.0 && MaskOptions::default().hole_mm > 0.0);
        let now: MaskOptions = serde_json::from_value(serde_json::to_value(MaskOptions::default()).unwrap()).unwrap();
        assert_eq!(now, MaskOptions::default());
    }

    /// A square grid of `n`×`n` cells of side `cell` in the plane y = `y`, facing −Y, centred on
    /// the Z axis; cells for which `skip(i, j)` holds are left out (a hole).
    fn grid(n: u32, cell: f32, y: f32, skip: impl Fn(u32, u32) -> bool) -> hairrecon_core::TriMesh {
        let half = n as f32 * cell / 2.0;
        let vertices = (0..=n)
            .flat_map(|j| (0..=n).map(move |i| Vec3::new(i as f32 * cell - half, y, j as f32 * cell - half)))
            .collect();
        let at = |i: u32, j: u32| j * (n + 1) + i;
        let triangles = (0..n)
            .flat_map(|j| (0..n).map(move |i| (i, j)))
            .filter(|&(i, j)| !skip(i, j))
            .flat_map(|(i, j)| [[at(i, j), at(i + 1, j), at(i + 1, j + 1)], [at(i, j), at(i + 1, j + 1), at(i, j + 1)]])
            .collect();
        hairrecon_core::TriMesh::new(vertices, triangles, None, None).unwrap()
    }

    #[test]
    fn a_hole_in_the_raw_mesh_takes_the_region_around_it_not_the_head_behind() {
        use hairrecon_core::Camera;
        // The raw mesh: a 20 cm square 2 cm in front of the head (a plane), with a 4 cm hole.
        let raw = Bvh::new(grid(20, 0.01, -0.02, |i, j| (8..12).contains(&i) && (8..12).contains(&j)));
        let head = Bvh::new(grid(4, 0.1, 0.0, |_, _| false));
        // The scalp: the head's upper half (z > 0); its lower half is the neck.
        let scalp = Bvh::new(grid(4, 0.1, 0.0, |_, j| j < 2));
        let cam = Camera::look_at(Vec3::new(0.0, -1.0, 0.0), Vec3::ZERO, Vec3::Z, 0.5, 64, 64).unwrap();
        let hits = ViewHits::cast(&cam, &raw, Some(&head));
        // A pixel a little above the centre (z about +1 cm): through the hole onto the scalp.
        let centre = 30 * 64 + 32;
        assert_eq!(hits.hits[centre].surface, Surface::Head, "the pixel looks through the hole");
        let image = RgbImage32 { width: 64, height: 64, data: vec![0.5; 64 * 64 * 3] };
        let n = raw.mesh().vertices.len();
        let render = |prob: f32, hole_mm: f32| {
            let surfaces = Surfaces { raw: &raw, head: &head, scalp: &scalp, hole: hole_mm * 1e-3 };
            silhouette(&hits, &surfaces, &vec![prob; n], &image, None, 0.0).data
        };
        // Hair around the hole: the hole is hair; skin around it: skin; without the fill, never hair.
        assert!((render(0.9, 50.0)[centre] - 0.9).abs() < 1e-5);
        assert!(render(0.1, 50.0)[centre] < 0.1 + 1e-5);
        assert_eq!(render(0.9, 0.0)[centre], 0.0);
        // The head's point under the hole is 2 cm behind and 1 cm across from the mesh: not within 1 cm.
        assert_eq!(render(0.9, 10.0)[centre], 0.0);
        // A pixel that meets the raw mesh keeps its probability; one that meets nothing stays 0.
        let on_mesh = 32 * 64 + 24;
        assert_eq!(hits.hits[on_mesh].surface, Surface::Raw);
        assert!((render(0.9, 50.0)[on_mesh] - 0.9).abs() < 1e-5);
        assert_eq!(render(0.9, 50.0)[0], 0.0);
        // Through a hole below the scalp (z < 0: the neck) the head is not hair.
        let raw_low = Bvh::new(grid(20, 0.01, -0.02, |i, j| (8..12).contains(&i) && (5..8).contains(&j)));
        let hits_low = ViewHits::cast(&cam, &raw_low, Some(&head));
        let below = 36 * 64 + 32;
        assert_eq!(hits_low.hits[below].surface, Surface::Head, "the pixel looks through the lower hole");
        let surfaces = Surfaces { raw: &raw_low, head: &head, scalp: &scalp, hole: 0.05 };
        let n_low = raw_low.mesh().vertices.len();
        assert_eq!(silhouette(&hits_low, &surfaces, &vec![0.9; n_low], &image, None, 0.0).data[below], 0.0);
    }

    /// A small linear congruential generator (Knuth's MMIX constants): reproducible test data
    /// without the rand crate.
    pub(crate) struct Lcg(pub(crate) u64);

    impl Lcg {
        /// The next value in [0, 1).
        pub(crate) fn next_f32(&mut self) -> f32 {
            self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }
    }
}
