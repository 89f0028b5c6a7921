//! Material editing by inverse rendering: the material (and, if asked, a low-resolution
//! environment map) that makes the layer reproduce an image, found with Adam through the
//! layer's own backward pass on whichever backend the [`crate::Renderer`] holds; then transfer
//! (one image's shape and light with another's material) and the grid of transfers.
//!
//! Parameterisation: every scale control point is `sign * exp(u)` with its sign taken
//! from the initial material, every exponent control point `exp(u)`, every env texel
//! channel `exp(w)`: exponents stay >= 0 and radiance > 0 without constraints, and Adam's
//! steps are relative changes, which suits numbers that span 1e-3 to 1e3.
//!
//! Loss, on the masked pixels: the mean over pixels and channels of
//! `(g(I) - g(T))^2 / c^2` with `g(x) = c ln(1 + x / c)` (`g(x) = x` below 0) and `c` the
//! target's mean over the mask: linear, so like the PSNR it is judged by, for the body of
//! the object, and logarithmic above it, so that a highlight that is not yet in its place
//! does not drown the gradient of everything else.
//!
//! Material and light are ambiguous (a brighter light and a darker material give the same
//! image). With `Light::Fit` two priors on the map's log radiance resolve it: smoothness
//! (squared differences between neighbouring texels, which also fills the directions that
//! no pixel sees) and a level: each channel's mean log radiance is held near the level at
//! which the initial material renders the target's mean brightness under a uniform light,
//! so the light's mean colour stays neutral, the material takes the object's colour and
//! keeps about the brightness of the preset it starts from, and the light takes the rest.
//!
//! Files: [`options`] (the light and the [`Options`]), [`inputs`] (what is fitted to:
//! loaded, masked, at the work size), `params.rs` (the free parameters above), `loss.rs`
//! (the data term, the priors, [`psnr`]), [`fit`](mod@fit) (Adam, [`adam`]), [`dir`] (fit folders:
//! checked, judged, written and read), [`transfer`] (transfer and the grid), [`plot`]
//! (loss.png).

pub mod adam;
pub mod dir;
pub mod fit;
pub mod inputs;
mod loss;
pub mod options;
mod params;
pub mod photo;
pub mod plot;
pub mod transfer;

pub use fit::{Fitted, fit};
pub use inputs::{Inputs, ObjectNormals};
pub use loss::psnr;
pub use options::{Light, Options};
