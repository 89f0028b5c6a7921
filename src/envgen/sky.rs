//! Daylight: the clear sky of Preetham, Shirley and Smits, "A Practical Analytic Model for
//! Daylight" (SIGGRAPH 1999) with a sun disc seen through the same atmosphere, and the CIE
//! standard overcast sky.
//!
//! Clear sky: luminance Y and chromaticity x, y each follow the Perez distribution
//! F(theta, gamma) = (1 + A e^(B / cos theta)) (1 + C e^(D gamma) + E cos^2 gamma) (theta
//! from the zenith, gamma from the sun), relative to the zenith's value, with the paper's
//! coefficients linear in turbidity T and its zenith luminance and chromaticity
//! (appendix A.2). The sun: 5778 K black-body light of 128 klux outside the atmosphere,
//! through Rayleigh scattering and aerosol (Angstrom) extinction along the relative air
//! mass of Kasten and Young (1989), per channel at 615, 545 and 465 nm. The sky's level
//! (its horizontal illuminance) is the light the beam loses at 545 nm, 0.6 of it reaching
//! the ground: E_sky = 0.6 E_0 (cos theta_s + 0.005) (1 - tau), so that the sun-to-sky
//! ratio is tau / (0.6 (1 - tau)) (about 7 for a clear sky and a high sun, 1 at T = 10).
//! The ground below the horizon is Lambertian: albedo times the horizontal illuminance of
//! sky and sun over pi.
//!
//! Scale: the map is divided by the sky's horizontal illuminance over pi (the radiance of
//! a uniform sky as bright), so that the sky's radiance is of order 1 whatever the sun.

use std::f64::consts::PI;

use super::colour::{luminance, mul, scale, temperature_rgb, xyy_to_rgb};
use super::raster::{self, Disc, direction, dot};
use crate::envmap::EnvMap;
use crate::error::{Result, invalid};

/// Angular radius of the sun disc, radians (0.2666 degrees).
pub const SUN_RADIUS: f64 = 0.004_653;

/// Solar illuminance outside the atmosphere, klux.
const SOLAR_ILLUMINANCE: f64 = 128.0;

/// Turbidities the clear-sky model is fitted over.
pub const TURBIDITY_RANGE: (f64, f64) = (2.0, 10.0);

/// A clear sky with a sun.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunSky {
    /// Sun elevation above the horizon, degrees, in [0, 90].
    pub elevation: f64,
    /// Sun azimuth, degrees: the map's phi (0 at +x, 90 at +z, towards the viewer).
    pub azimuth: f64,
    /// Atmospheric turbidity, in [2, 10]: 2 a very clear sky, 10 a hazy one.
    pub turbidity: f64,
    /// Ground albedo, linear RGB, each in [0, 1].
    pub ground: [f64; 3],
    /// Whether the sun disc is drawn (its light on the ground counts either way).
    pub sun: bool,
}

/// The Perez coefficients (A..E) of Y, x and y for turbidity `t` (Preetham et al.,
/// appendix A.2).
fn perez_coefficients(t: f64) -> [[f64; 5]; 3] {
    [
        [
            0.1787 * t - 1.4630,
            -0.3554 * t + 0.4275,
            -0.0227 * t + 5.3251,
            0.1206 * t - 2.5771,
            -0.0670 * t + 0.3703,
        ],
        [
            -0.0193 * t - 0.2592,
            -0.0665 * t + 0.0008,
            -0.0004 * t + 0.2125,
            -0.0641 * t - 0.8989,
            -0.0033 * t + 0.0452,
        ],
        [
            -0.0167 * t - 0.2608,
            -0.0950 * t + 0.0092,
            -0.0079 * t + 0.2102,
            -0.0441 * t - 1.6537,
            -0.0109 * t + 0.0529,
        ],
    ]
}

fn perez(c: &[f64; 5], cos_theta: f64, gamma: f64) -> f64 {
    // the distribution's horizon limit: e^(B / cos theta) -> 0 (B < 0 for T >= 2)
    let cos_theta = cos_theta.max(1e-3);
    (1.0 + c[0] * (c[1] / cos_theta).exp())
        * (1.0 + c[2] * (c[3] * gamma).exp() + c[4] * gamma.cos().powi(2))
}

/// Zenith chromaticity coordinate: [T^2, T, 1] M [theta_s^3, theta_s^2, theta_s, 1].
fn zenith_chroma(m: [[f64; 4]; 3], t: f64, ts: f64) -> f64 {
    let tv = [t * t, t, 1.0];
    let sv = [ts * ts * ts, ts * ts, ts, 1.0];
    (0..3)
        .map(|i| tv[i] * (0..4).map(|j| m[i][j] * sv[j]).sum::<f64>())
        .sum()
}

/// The sky's parameters, ready to evaluate.
#[derive(Clone, Debug)]
pub struct Model {
    sun_dir: [f64; 3],
    theta_s: f64,
    coef: [[f64; 5]; 3],
    zenith: [f64; 3],
    /// Radiance of the sun disc (kcd/m^2 before scaling), RGB.
    sun_radiance: [f64; 3],
    /// Radiance of the ground (kcd/m^2 before scaling), RGB.
    ground: [f64; 3],
    /// Multiplies everything: pi over the sky's horizontal illuminance.
    scale: f64,
}

impl SunSky {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        let bad = |what: &str, v: f64, range: &str| {
            invalid!("sun-sky: {what} is {v}; it must be in {range}")
        };
        if !(0.0..=90.0).contains(&self.elevation) {
            return Err(bad("sun elevation", self.elevation, "[0, 90] degrees"));
        }
        if !self.azimuth.is_finite() {
            return Err(bad("sun azimuth", self.azimuth, "finite degrees"));
        }
        if !(TURBIDITY_RANGE.0..=TURBIDITY_RANGE.1).contains(&self.turbidity) {
            return Err(bad("turbidity", self.turbidity, "[2, 10]"));
        }
        if let Some(&g) = self.ground.iter().find(|g| !(0.0..=1.0).contains(*g)) {
            return Err(bad("ground albedo", g, "[0, 1]"));
        }
        Ok(())
    }

    /// The model with its scale.
    pub fn model(&self) -> Result<Model> {
        self.validate()?;
        let t = self.turbidity;
        let theta_s = (90.0 - self.elevation).to_radians();
        let sun_dir = direction(self.elevation.to_radians(), self.azimuth.to_radians());
        let chi = (4.0 / 9.0 - t / 120.0) * (PI - 2.0 * theta_s);
        let y_z = (4.0453 * t - 4.9710) * chi.tan() - 0.2155 * t + 2.4192;
        let x_z = zenith_chroma(
            [
                [0.00166, -0.00375, 0.00209, 0.0],
                [-0.02903, 0.06377, -0.03202, 0.00394],
                [0.11693, -0.21196, 0.06052, 0.25886],
            ],
            t,
            theta_s,
        );
        let yc_z = zenith_chroma(
            [
                [0.00275, -0.00610, 0.00317, 0.0],
                [-0.04214, 0.08970, -0.04153, 0.00516],
                [0.15346, -0.26756, 0.06670, 0.26688],
            ],
            t,
            theta_s,
        );
        let coef = perez_coefficients(t);
        let zenith = [0, 1, 2].map(|k| {
            let z = [y_z, x_z, yc_z][k];
            z / perez(&coef[k], 1.0, theta_s)
        });
        let mut m = Model {
            sun_dir,
            theta_s,
            coef,
            zenith,
            sun_radiance: sun_radiance(t, theta_s),
            ground: [0.0; 3],
            scale: 1.0,
        };
        // The sky's level from the light the beam loses: Preetham's zenith luminance gave
        // a sky brighter than that at high turbidity (sun-to-sky 0.42 at T = 10, sun at
        // the zenith); its distribution and colours are kept.
        let lost = 1.0 - transmittance(t, theta_s)[1];
        let want = DIFFUSE_SHARE * SOLAR_ILLUMINANCE * (theta_s.cos().max(0.0) + TWILIGHT) * lost;
        let level = want / luminance(m.sky_illuminance()).max(1e-12);
        m.zenith[0] *= level;
        let sky_e = m.sky_illuminance();
        let sun_e = m.sun_illuminance();
        let e = [0, 1, 2].map(|k| sky_e[k] + sun_e[k]);
        m.ground = [0, 1, 2].map(|k| self.ground[k] * e[k] / PI);
        m.scale = PI / luminance(sky_e).max(1e-12);
        Ok(m)
    }

    /// The map, `height` x `width`, equirect.
    pub fn env(&self, height: usize, width: usize) -> Result<EnvMap> {
        raster::check_size(height, width)?;
        let m = self.model()?;
        let mut texels = raster::rasterise(height, width, |w| m.radiance(w));
        if self.sun {
            raster::add_disc(&mut texels, height, width, &m.sun_disc(), |w| w[1] >= 0.0);
        }
        raster::finish(height, width, texels)
    }
}

/// Transmittance of the direct beam at 615, 545 and 465 nm: Rayleigh and aerosol
/// (Angstrom, beta from turbidity as in Preetham et al.) extinction along the relative air
/// mass of Kasten and Young (1989).
fn transmittance(turbidity: f64, theta_s: f64) -> [f64; 3] {
    let z_deg = theta_s.to_degrees().min(90.0);
    let air_mass = 1.0 / (theta_s.cos().max(0.0) + 0.505_72 * (96.079_95 - z_deg).powf(-1.6364));
    let beta = 0.046_08 * turbidity - 0.045_86;
    [0.615, 0.545, 0.465].map(|lambda: f64| {
        let rayleigh = 0.008_735 * lambda.powf(-4.08);
        let aerosol = beta * lambda.powf(-1.3);
        (-(rayleigh + aerosol) * air_mass).exp()
    })
}

/// Share of the light taken from the direct beam that reaches the ground as sky light.
const DIFFUSE_SHARE: f64 = 0.6;

/// The twilight floor of the sky's level: the sun's cosine counts as at least this much
/// more (about 0.4 klux of sky light with the sun on the horizon).
const TWILIGHT: f64 = 0.005;

/// Radiance of the sun disc seen through the atmosphere, kcd/m^2, RGB.
fn sun_radiance(turbidity: f64, theta_s: f64) -> [f64; 3] {
    let omega = 2.0 * PI * (1.0 - SUN_RADIUS.cos());
    // klux / sr = kcd/m^2
    scale(
        mul(temperature_rgb(5778.0), transmittance(turbidity, theta_s)),
        SOLAR_ILLUMINANCE / omega,
    )
}

impl Model {
    /// Sky radiance (without the disc) in kcd/m^2 before scaling, RGB, above the horizon.
    fn sky(&self, w: [f64; 3]) -> [f64; 3] {
        let cos_theta = w[1].max(0.0);
        let gamma = dot(w, self.sun_dir).clamp(-1.0, 1.0).acos();
        let v = [0, 1, 2].map(|k| self.zenith[k] * perez(&self.coef[k], cos_theta, gamma));
        xyy_to_rgb(v[1], v[2], v[0].max(0.0))
    }

    /// The map's radiance (sky above the horizon, ground below), scaled; the sun disc is
    /// placed separately ([`Model::sun_disc`]).
    pub fn radiance(&self, w: [f64; 3]) -> [f64; 3] {
        let l = if w[1] >= 0.0 {
            self.sky(w)
        } else {
            self.ground
        };
        scale(l, self.scale)
    }

    /// The sun disc, scaled.
    pub fn sun_disc(&self) -> Disc {
        Disc {
            dir: self.sun_dir,
            radius: SUN_RADIUS,
            radiance: scale(self.sun_radiance, self.scale),
        }
    }

    /// Horizontal illuminance of the sky alone (unscaled), RGB, by a fixed quadrature
    /// (the same at every map size).
    fn sky_illuminance(&self) -> [f64; 3] {
        let (nt, np) = (64, 128);
        let mut e = [0.0; 3];
        for i in 0..nt {
            let theta = (i as f64 + 0.5) / nt as f64 * PI / 2.0;
            let d = theta.sin() * theta.cos() * (PI / 2.0 / nt as f64) * (2.0 * PI / np as f64);
            for j in 0..np {
                let phi = (j as f64 + 0.5) / np as f64 * 2.0 * PI;
                let l = self.sky(direction(PI / 2.0 - theta, phi));
                for k in 0..3 {
                    e[k] += l[k] * d;
                }
            }
        }
        e
    }

    /// Horizontal illuminance of the sun alone (unscaled), RGB.
    fn sun_illuminance(&self) -> [f64; 3] {
        let omega = 2.0 * PI * (1.0 - SUN_RADIUS.cos());
        scale(self.sun_radiance, omega * self.theta_s.cos().max(0.0))
    }

    /// The sun's horizontal illuminance over the sky's.
    pub fn sun_to_sky(&self) -> f64 {
        luminance(self.sun_illuminance()) / luminance(self.sky_illuminance())
    }
}

/// The CIE standard overcast sky: luminance (1 + 2 sin(elevation)) / 3 of the zenith's,
/// one colour, over a Lambertian ground.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Overcast {
    /// Colour of the sky (linear RGB, luminance 1: a grey with a slight tint).
    pub tint: [f64; 3],
    /// Ground albedo, linear RGB, each in [0, 1].
    pub ground: [f64; 3],
}

impl Overcast {
    /// Radiance in direction `w`. The zenith is 9/7 so that the horizontal illuminance
    /// over pi is 1: the integral of (1 + 2 cos theta) / 3 cos theta over the hemisphere
    /// is 7 pi / 9.
    pub fn radiance(&self, w: [f64; 3]) -> [f64; 3] {
        let zenith = 9.0 / 7.0;
        if w[1] >= 0.0 {
            scale(self.tint, zenith * (1.0 + 2.0 * w[1]) / 3.0)
        } else {
            mul(self.ground, self.tint)
        }
    }

    /// The map, `height` x `width`, equirect.
    pub fn env(&self, height: usize, width: usize) -> Result<EnvMap> {
        raster::check_size(height, width)?;
        if let Some(&g) = self.ground.iter().find(|g| !(0.0..=1.0).contains(*g)) {
            return Err(invalid!(
                "overcast: ground albedo is {g}; it must be in [0, 1]"
            ));
        }
        if let Some(&t) = self.tint.iter().find(|t| !(t.is_finite() && **t >= 0.0)) {
            return Err(invalid!("overcast: tint channel is {t}; it must be >= 0"));
        }
        raster::finish(
            height,
            width,
            raster::rasterise(height, width, |w| self.radiance(w)),
        )
    }
}
