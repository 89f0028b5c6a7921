//! Fitting the DSBRDF to an isotropic BRDF.

use crate::brdf::Isotropic;
use crate::error::Result;
use crate::material::Material;

/// How many lobes to fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lobes {
    /// Exactly this many (1 to 3).
    Fixed(usize),
    /// 1, 2 and 3, keeping the fewest whose error is within [`Options::tolerance`] of
    /// the 3-lobe fit's.
    Auto,
}

/// The fitter's settings.
#[derive(Clone, Debug)]
pub struct Options {
    /// Lobe count.
    pub lobes: Lobes,
    /// Relative slack over the 3-lobe error allowed to a fit with fewer lobes.
    pub tolerance: f64,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            lobes: Lobes::Auto,
            tolerance: 0.05,
        }
    }
}

/// One fit.
#[derive(Clone, Debug)]
pub struct Fit {
    /// Lobes used (the others have m0 = 0).
    pub lobes: usize,
    /// The fitted material.
    pub material: Material,
    /// The BRDF's relative RMSE, cosine-weighted over the hemisphere ([`brdf_error`]).
    pub error: f64,
}

/// The fits tried for one BRDF.
#[derive(Clone, Debug)]
pub struct Fitted {
    /// One fit per lobe count tried, ascending.
    pub fits: Vec<Fit>,
    /// Index into `fits` of the one kept.
    pub chosen: usize,
}

impl Fitted {
    /// The fit kept.
    pub fn best(&self) -> &Fit {
        &self.fits[self.chosen]
    }
}

/// Fits the DSBRDF to `brdf`; `name` names the material.
pub fn fit(_brdf: &dyn Isotropic, _name: &str, _options: &Options) -> Result<Fitted> {
    todo!()
}

/// The relative RMSE of `model` against `measured`, weighted by cos theta_i cos theta_o
/// over pairs of directions in the upper hemisphere.
pub fn brdf_error(_model: &dyn Isotropic, _measured: &dyn Isotropic) -> f64 {
    todo!()
}
