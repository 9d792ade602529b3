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

pub use crate::aa_output::{AaMethod, AaOutput};
use crate::error::RasterError;
use crate::image::Image;
use crate::rasterize::Buffers;
use crate::screen::{Screen, SegmentGrads};
use crate::{aa_nvdiffrast, aa_ours, aa_splat};

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
    if grads.len() != screen.prims.len() {
        grads.reset(screen.prims.len());
    }
    match saved.method {
        AaMethod::Ours => aa_ours::backward(screen, buf, saved, d_image, d_attrs, grads),
        AaMethod::Nvdiffrast => aa_nvdiffrast::backward(screen, buf, saved, d_image, d_attrs, grads),
        AaMethod::Splat => aa_splat::backward(screen, buf, saved, d_image, d_attrs, grads),
    }
    Ok(())
}
