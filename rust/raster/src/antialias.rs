//! Anti-aliasing as its own differentiable op: one entry point for the three methods.
//!
//! `antialias_forward` reads the hard [`Buffers`] of [`crate::rasterize()`] and the primitives of the
//! [`Screen`], and writes an anti-aliased image plus a saved buffer into an [`AaOutput`];
//! `antialias_backward` consumes that saved buffer and the gradient of the loss with respect to the
//! anti-aliased image, and returns the gradient with respect to the hard attributes (to pass on to
//! [`crate::attributes_backward`]) and with respect to the corners of the primitives (to pass on to
//! [`Screen::backward_vertices`]). This is nvdiffrast's `antialias_fwd`/`antialias_grad` split
//! (Laine et al. 2020, "Modular primitives for high-performance differentiable rendering").
//!
//! - [`AaMethod::Ours`]: Dr.Hair's anti-aliasing, [`crate::aa_ours`].
//! - [`AaMethod::Nvdiffrast`]: selective silhouette anti-aliasing, [`crate::aa_nvdiffrast`].
//! - [`AaMethod::Splat`]: splatting of re-projected samples, [`crate::aa_splat`].

use glam::Vec2;

use crate::error::RasterError;
use crate::image::Image;
use crate::rasterize::Buffers;
use crate::screen::{Screen, SegmentGrads};
use crate::{aa_nvdiffrast, aa_ours, aa_splat};

/// The anti-aliasing method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AaMethod {
    Ours,
    Nvdiffrast,
    Splat,
}

impl AaMethod {
    pub const ALL: [AaMethod; 3] = [AaMethod::Ours, AaMethod::Nvdiffrast, AaMethod::Splat];

    pub fn name(self) -> &'static str {
        match self {
            AaMethod::Ours => "ours",
            AaMethod::Nvdiffrast => "nvdiffrast",
            AaMethod::Splat => "splat",
        }
    }

    /// Parses `ours`, `nvdiffrast` or `splat`.
    pub fn parse(s: &str) -> Option<Self> {
        AaMethod::ALL.into_iter().find(|m| m.name() == s)
    }
}

/// The anti-aliased image and what the backward pass needs, reused between calls.
#[derive(Debug, Clone)]
pub struct AaOutput {
    pub method: AaMethod,
    /// The anti-aliased attributes, same shape as the input attributes.
    pub image: Image,
    /// Per pixel and neighbour slot: the chosen edge (method-specific code, `u32::MAX` for none).
    pub(crate) edges: Vec<u32>,
    /// Per pixel and neighbour slot: the edge distance or crossing parameter.
    pub(crate) vals: Vec<f32>,
}

impl AaOutput {
    pub fn new(method: AaMethod) -> Self {
        Self { method, image: Image::default(), edges: Vec::new(), vals: Vec::new() }
    }

    /// The saved edge choices (one code per pixel and neighbour slot; `u32::MAX` for none). Two
    /// renders with equal ids and equal edge choices are joined by a smooth path of the AA output,
    /// which is what a finite-difference check needs.
    pub fn saved_edges(&self) -> &[u32] {
        &self.edges
    }
}

pub(crate) const NONE: u32 = u32::MAX;

/// The 8-neighbourhood, in an order where slot `7 − k` is the opposite of slot `k`.
pub(crate) const N8: [(i32, i32); 8] = [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)];

/// Anti-aliases `buf.attrs` with `out.method`. `out` is overwritten.
pub fn antialias_forward(screen: &Screen, buf: &Buffers, out: &mut AaOutput) {
    match out.method {
        AaMethod::Ours => aa_ours::forward(screen, buf, out),
        AaMethod::Nvdiffrast => aa_nvdiffrast::forward(screen, buf, out),
        AaMethod::Splat => aa_splat::forward(screen, buf, out),
    }
}

/// Backward of [`antialias_forward`]: `d_image` is ∂L/∂(anti-aliased image). Writes ∂L/∂attrs into
/// `d_attrs` (overwritten) and adds the corner gradients into `grads` (sized by the caller with
/// [`SegmentGrads::reset`]).
pub fn antialias_backward(
    screen: &Screen,
    buf: &Buffers,
    saved: &AaOutput,
    d_image: &Image,
    d_attrs: &mut Image,
    grads: &mut SegmentGrads,
) -> Result<(), RasterError> {
    let a = &buf.attrs;
    d_image.check_shape("the image gradient", a.width, a.height, a.channels)?;
    d_attrs.reset(a.width, a.height, a.channels);
    if grads.corners.len() != screen.prims.len() {
        grads.reset(screen.prims.len());
    }
    match saved.method {
        AaMethod::Ours => aa_ours::backward(screen, buf, saved, d_image, d_attrs, grads),
        AaMethod::Nvdiffrast => aa_nvdiffrast::backward(screen, buf, saved, d_image, d_attrs, grads),
        AaMethod::Splat => aa_splat::backward(screen, buf, saved, d_image, d_attrs, grads),
    }
    Ok(())
}

/// Adds a list of per-band corner gradients `(prim·4 + corner, gradient)` into `grads`.
pub(crate) fn scatter_corners(parts: Vec<Vec<(u32, Vec2)>>, grads: &mut SegmentGrads) {
    for part in parts {
        for (code, g) in part {
            grads.corners[(code >> 2) as usize][(code & 3) as usize] += g;
        }
    }
}
