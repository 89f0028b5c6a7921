//! Levels of detail: approximations of the layer that skip work a scene does not need,
//! each with a forward and a backward pass on any [`Backend`], and the choice of the
//! cheapest one that meets an error budget ([`choose`]).
//!
//! A [`Method`] composes three reductions:
//!
//! - **Environment levels** (`envF`): the map averaged over F x F texel blocks, each
//!   block one light with the block's total solid angle, its solid-angle-weighted mean
//!   radiance and its mean direction. The backward pass is the average's adjoint.
//! - **Kept texels** (`keepK`): the K texels with the most energy (sum over channels of
//!   |L| d_omega) are taken out of the blocks and kept at full resolution: a sun next to
//!   a dim sky keeps its sharp highlight while the sky is averaged.
//! - **Normal tables** (`tableR`, orthographic cameras): with w_p fixed the image is a
//!   function of the normal alone. The layer is evaluated at the nodes of an R x R grid
//!   over the stereographic plane of normals (u, v) = (n.x, n.y) / (1 + n.z), only where
//!   some pixel's stencil needs one, and each pixel is interpolated from the 6 x 6 nodes
//!   around it (Lagrange, degree 5 along each axis). Kept texels stay exact per pixel;
//!   normals that are not unit length, or too far behind the sphere, stay exact too. The
//!   backward pass scatters the upstream gradient onto the nodes (the interpolation's
//!   adjoint) and runs the exact backward there; dLoss/dn interpolates the nodes' exact
//!   3 x 3 Jacobians dI/dn.
//!
//! Errors are relative: max |I - I_exact| over max I_exact (and the same for each
//! gradient).

mod choose;
mod cull;
mod light;
mod table;

pub use choose::{Choice, Chooser, ESTIMATE_BUDGET, Estimate, SAFETY, SAFETY_SUMS, choose};

use crate::Backend;
use crate::error::{Error, Result};
use crate::prepare::Prepared;
use crate::scene::{Gradients, Image, Scene, Wanted};

/// Largest block side of an environment level.
pub const MAX_ENV_FACTOR: usize = 64;
/// Table resolutions [`choose`] tries.
pub const TABLE_SIZES: [usize; 12] = [16, 24, 32, 48, 64, 96, 128, 160, 192, 224, 256, 384];

/// A level of detail: how the layer is approximated. `Method::EXACT` is the layer itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Method {
    /// Side of the texel blocks the map is averaged over (1: full resolution).
    pub env_factor: usize,
    /// How many of the brightest texels stay at full resolution, outside the blocks.
    pub keep: usize,
    /// Orthographic cameras: the resolution R of the normal table (None: every pixel is
    /// evaluated).
    pub table: Option<usize>,
    /// Orthographic cameras: lights are culled per group of normals within this budget,
    /// in billionths of the image's largest value (None: no culling).
    pub cull: Option<u64>,
}

impl Method {
    /// The layer, unapproximated.
    pub const EXACT: Method = Method {
        env_factor: 1,
        keep: 0,
        table: None,
        cull: None,
    };

    /// The culling budget relative to the image's largest value (0 without culling).
    pub fn cull_budget(&self) -> f64 {
        self.cull.map_or(0.0, |b| b as f64 / 1e9)
    }

    /// Whether this is the exact layer.
    pub fn is_exact(&self) -> bool {
        // keeping texels at full resolution beside a full-resolution map changes nothing
        self.table.is_none() && self.env_factor == 1 && self.cull.is_none()
    }

    /// Checks the parameters against a scene: a table needs an orthographic camera.
    pub fn validate(&self, scene: &Scene) -> Result<()> {
        if self.env_factor == 0 || self.env_factor > MAX_ENV_FACTOR {
            return Err(Error::Invalid(format!(
                "method {self}: the block side must be 1 to {MAX_ENV_FACTOR}"
            )));
        }
        if self.cull.is_some() && !scene.camera.is_orthographic() {
            return Err(Error::Invalid(format!(
                "method {self}: culling needs an orthographic camera (the view direction must \
                 be the same for every pixel)"
            )));
        }
        if let Some(r) = self.table {
            if !(4..=4096).contains(&r) {
                return Err(Error::Invalid(format!(
                    "method {self}: the table resolution must be 4 to 4096"
                )));
            }
            if !scene.camera.is_orthographic() {
                return Err(Error::Invalid(format!(
                    "method {self}: normal tables need an orthographic camera (the view \
                     direction must be the same for every pixel)"
                )));
            }
        }
        Ok(())
    }
}

impl Default for Method {
    fn default() -> Self {
        Method::EXACT
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut parts = Vec::new();
        if let Some(r) = self.table {
            parts.push(format!("table{r}"));
        }
        if self.env_factor > 1 {
            parts.push(format!("env{}", self.env_factor));
        }
        if self.keep > 0 {
            parts.push(format!("keep{}", self.keep));
        }
        if self.cull.is_some() {
            parts.push(format!("cull{:e}", self.cull_budget()));
        }
        if parts.is_empty() {
            f.write_str("exact")
        } else {
            f.write_str(&parts.join("+"))
        }
    }
}

impl std::str::FromStr for Method {
    type Err = String;
    /// "exact", or '+'-joined parts: `envF` (F = 1 to 64), `keepK`, `tableR`; e.g.
    /// "table96+env2+keep16".
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let bad = || {
            format!(
                "unknown method '{s}': expected 'exact' or parts joined by '+': envF (blocks of \
                 F x F texels), keepK (the K brightest texels kept), tableR (an R x R normal \
                 table), cullB (lights culled within B of the largest value), e.g. \
                 table96+env2+keep16"
            )
        };
        let mut m = Method::EXACT;
        if s == "exact" {
            return Ok(m);
        }
        let (mut env, mut keep, mut table, mut cull) = (false, false, false, false);
        for part in s.split('+') {
            let num = |prefix: &str| -> Option<usize> { part.strip_prefix(prefix)?.parse().ok() };
            if let (Some(f), false) = (num("env"), env) {
                env = true;
                m.env_factor = f;
            } else if let (Some(k), false) = (num("keep"), keep) {
                keep = true;
                m.keep = k;
            } else if let (Some(r), false) = (num("table"), table) {
                table = true;
                m.table = Some(r);
            } else if let (Some(b), false) = (
                part.strip_prefix("cull")
                    .and_then(|b| b.parse::<f64>().ok()),
                cull,
            ) {
                cull = true;
                if !(b > 0.0 && b < 1.0) {
                    return Err(format!(
                        "method '{s}': the culling budget must be in (0, 1), e.g. cull1e-4"
                    ));
                }
                m.cull = Some(((b * 1e9).round() as u64).max(1));
            } else {
                return Err(bad());
            }
        }
        if m.env_factor == 0 || m.env_factor > MAX_ENV_FACTOR {
            return Err(format!(
                "method '{s}': the block side must be 1 to {MAX_ENV_FACTOR}"
            ));
        }
        if matches!(m.table, Some(r) if !(4..=4096).contains(&r)) {
            return Err(format!(
                "method '{s}': the table resolution must be 4 to 4096"
            ));
        }
        Ok(m)
    }
}

/// The image of `scene` under `method`.
pub fn render(backend: &dyn Backend, scene: &Scene, method: &Method) -> Result<Image> {
    method.validate(scene)?;
    let prep = Prepared::new(scene);
    Plan::new(backend, &prep, &scene.env, method, &prep.pixels)?.forward(backend)
}

/// The gradients of `scene` under `method`, for upstream dLoss/dImage `upstream`: the
/// exact vector-Jacobian product of the approximation.
pub fn backward(
    backend: &dyn Backend,
    scene: &Scene,
    upstream: &Image,
    method: &Method,
) -> Result<Gradients> {
    method.validate(scene)?;
    if (upstream.width, upstream.height) != (scene.normals.width, scene.normals.height) {
        return Err(Error::Invalid(format!(
            "upstream: {}x{} given for a {}x{} image",
            upstream.width, upstream.height, scene.normals.width, scene.normals.height
        )));
    }
    let prep = Prepared::new(scene);
    Plan::new(backend, &prep, &scene.env, method, &prep.pixels)?.backward(
        backend,
        upstream,
        Wanted::ALL,
    )
}

/// The image of `scene` by the cheapest method whose estimated error is within `tol`, and
/// that choice.
pub fn render_within(backend: &dyn Backend, scene: &Scene, tol: f64) -> Result<(Image, Choice)> {
    Chooser::default().render_within(backend, scene, tol)
}

/// The gradients of `scene` by the cheapest method whose estimated errors (image and
/// every gradient) are within `tol`, and that choice.
pub fn backward_within(
    backend: &dyn Backend,
    scene: &Scene,
    upstream: &Image,
    tol: f64,
) -> Result<(Gradients, Choice)> {
    Chooser::default().backward_within(backend, scene, upstream, tol)
}

impl Chooser {
    /// [`render_within`] with these settings.
    pub fn render_within(
        &self,
        backend: &dyn Backend,
        scene: &Scene,
        tol: f64,
    ) -> Result<(Image, Choice)> {
        let prep = Prepared::new(scene);
        let (choice, plan) = choose::choose_plan(self, backend, &prep, scene, tol, None)?;
        Ok((plan.forward(backend)?, choice))
    }

    /// [`backward_within`] with these settings.
    pub fn backward_within(
        &self,
        backend: &dyn Backend,
        scene: &Scene,
        upstream: &Image,
        tol: f64,
    ) -> Result<(Gradients, Choice)> {
        let prep = Prepared::new(scene);
        let (choice, plan) = choose::choose_plan(self, backend, &prep, scene, tol, Some(upstream))?;
        Ok((plan.backward(backend, upstream, Wanted::ALL)?, choice))
    }
}

pub(crate) use plan::Plan;

mod plan;
