//! Built-in materials: the 90 MERL materials fitted by [`crate::fit_brdf`] (their control
//! points ship in `data/merl/fits.json`, which `matedit fit-brdf --nbrdf
//! data/merl/merl_nbrdf.json --bundle data/merl/fits.json` regenerates), and a handful of
//! plausible parameter sets made by hand. The bundle format of that file ([`Bundle`]) lives
//! here, beneath the fit that writes it.
//!
//! Each hand-made preset has up to three lobes, f = sum_s (exp(m0_s x^m1_s) - 1) per channel:
//! - a diffuse lobe (m1 = 0, so f = exp(m0) - 1 is constant), with m0 = ln(1 + rho / pi)
//!   for a Lambertian albedo rho;
//! - glossy lobes (m1 from 4 to 400), whose scale can rise towards grazing theta_d
//!   (a Fresnel-like ramp over the last spline control points).
//!
//! The scales are chosen so that the directional albedo stays below 1 and renders under
//! the default environment have values of order 0.1 to 10.

use serde::{Deserialize, Serialize};

use crate::material::{Material, N_CHANNELS, N_LOBES, N_PARAMS, idx, material_from_ctrl};
use crate::spline::N_CTRL_POINTS;

/// The preset used when no material is given.
pub const DEFAULT: &str = "red-specular-plastic";

/// The fitted MERL materials, as `matedit fit-brdf --bundle` writes them.
const MERL_FITS: &str = include_str!("../data/merl/fits.json");

/// No ramp: the lobe is the same at every theta_d.
const FLAT: [f64; N_CTRL_POINTS] = [1.0; N_CTRL_POINTS];
/// A Fresnel-like rise of the scale towards theta_d = pi/2.
const FRESNEL: [f64; N_CTRL_POINTS] = [1.0, 1.0, 1.0, 1.1, 1.4, 2.0];

/// One lobe: scale m0 per channel, exponent m1, and the scale's ramp over theta_d.
#[derive(Clone, Copy, Debug)]
struct Lobe {
    m0: [f64; N_CHANNELS],
    m1: f64,
    ramp: [f64; N_CTRL_POINTS],
}

const NONE: Lobe = Lobe {
    m0: [0.0; N_CHANNELS],
    m1: 0.0,
    ramp: FLAT,
};

/// A Lambertian lobe of albedo `rho` per channel: exp(m0) - 1 = rho / pi.
const fn diffuse(m0: [f64; N_CHANNELS]) -> Lobe {
    Lobe {
        m0,
        m1: 0.0,
        ramp: FLAT,
    }
}

/// A built-in material.
#[derive(Clone, Debug)]
pub struct Preset {
    /// The name used with `--preset`.
    pub name: &'static str,
    /// One line saying what it is.
    pub description: String,
    material: Material,
}

impl Preset {
    /// The preset as a [`Material`].
    pub fn material(&self) -> Material {
        self.material.clone()
    }
}

/// A hand-made material.
#[derive(Clone, Copy, Debug)]
struct Handmade {
    name: &'static str,
    description: &'static str,
    lobes: [Lobe; N_LOBES],
}

impl Handmade {
    /// The 108 control points.
    pub fn ctrl(&self) -> [f64; N_PARAMS] {
        let mut ctrl = [0.0; N_PARAMS];
        for (s, lobe) in self.lobes.iter().enumerate() {
            for k in 0..N_CHANNELS {
                for j in 0..N_CTRL_POINTS {
                    ctrl[idx(k, s, 0, j)] = lobe.m0[k] * lobe.ramp[j];
                    ctrl[idx(k, s, 1, j)] = lobe.m1;
                }
            }
        }
        ctrl
    }
}

/// ln(1 + rho / pi) for the albedos used below, precomputed because `ln` is not const.
const fn lambert(rho: [f64; N_CHANNELS]) -> Lobe {
    // exp(m0) - 1 = rho / pi; for rho / pi <= 0.26, m0 = y - y^2/2 + y^3/3 - y^4/4 is
    // accurate to 1e-3 relative, plenty for a preset.
    let mut m0 = [0.0; N_CHANNELS];
    let mut k = 0;
    while k < N_CHANNELS {
        let y = rho[k] / std::f64::consts::PI;
        m0[k] = y - y * y / 2.0 + y * y * y / 3.0 - y * y * y * y / 4.0;
        k += 1;
    }
    diffuse(m0)
}

const HANDMADE: [Handmade; 5] = [
    Handmade {
        name: "plastic-red",
        description: "glossy red plastic: red diffuse base, white highlight (hand-made)",
        lobes: [
            lambert([0.55, 0.06, 0.04]),
            Lobe {
                m0: [0.7; 3],
                m1: 200.0,
                ramp: FRESNEL,
            },
            Lobe {
                m0: [0.05; 3],
                m1: 20.0,
                ramp: FRESNEL,
            },
        ],
    },
    Handmade {
        name: "gold",
        description: "polished gold: no diffuse, a tinted glossy lobe and a faint haze",
        lobes: [
            NONE,
            Lobe {
                m0: [2.9, 2.45, 1.35],
                m1: 200.0,
                ramp: FLAT,
            },
            Lobe {
                m0: [0.10, 0.07, 0.02],
                m1: 30.0,
                ramp: FLAT,
            },
        ],
    },
    Handmade {
        name: "clay",
        description: "terracotta clay: rough orange-brown diffuse with a faint broad sheen",
        lobes: [
            lambert([0.50, 0.30, 0.20]),
            Lobe {
                m0: [0.03; 3],
                m1: 4.0,
                ramp: FRESNEL,
            },
            NONE,
        ],
    },
    Handmade {
        name: "chrome-ish",
        description: "brushed chrome: a sharp neutral reflection (blurred at 64x128) and a soft halo",
        lobes: [
            NONE,
            Lobe {
                m0: [3.3; 3],
                m1: 400.0,
                ramp: FLAT,
            },
            Lobe {
                m0: [0.15; 3],
                m1: 40.0,
                ramp: FLAT,
            },
        ],
    },
    Handmade {
        name: "matte-white",
        description: "ideal white Lambertian, albedo 0.8 (a reference for lighting)",
        lobes: [lambert([0.8; 3]), NONE, NONE],
    },
];

/// Every built-in preset: the fitted MERL materials in name order, the default first,
/// then the hand-made ones.
pub fn all() -> &'static [Preset] {
    static ALL: std::sync::OnceLock<Vec<Preset>> = std::sync::OnceLock::new();
    ALL.get_or_init(|| {
        let bundle = Bundle::parse(MERL_FITS).expect("data/merl/fits.json is checked by the tests");
        let mut out: Vec<Preset> = bundle
            .materials
            .iter()
            .zip(bundle.materials())
            .map(|(entry, material)| Preset {
                name: leak(&entry.name),
                description: format!(
                    "MERL {}: measured, fitted with {} lobe{} (BRDF error {:.3})",
                    entry.name,
                    entry.lobes,
                    if entry.lobes == 1 { "" } else { "s" },
                    entry
                        .brdf_error
                        .get(entry.lobes - 1)
                        .copied()
                        .unwrap_or(f64::NAN)
                ),
                material,
            })
            .collect();
        if let Some(i) = out.iter().position(|p| p.name == DEFAULT) {
            let p = out.remove(i);
            out.insert(0, p);
        }
        out.extend(HANDMADE.iter().map(|h| Preset {
            name: h.name,
            description: h.description.to_string(),
            material: Material {
                name: h.name.to_string(),
                ctrl: h.ctrl(),
            },
        }));
        out
    })
}

/// The fitted MERL materials alone (the presets before the hand-made ones), in the order of
/// [`all`].
pub fn merl() -> &'static [Preset] {
    let all = all();
    &all[..all.len() - HANDMADE.len()]
}

/// A name that lives as long as the presets (they are built once).
fn leak(name: &str) -> &'static str {
    Box::leak(name.to_string().into_boxed_str())
}

/// The preset names, the default first.
pub fn names() -> Vec<&'static str> {
    all().iter().map(|p| p.name).collect()
}

/// The material of the preset called `name`, if there is one.
pub fn lookup(name: &str) -> Option<Material> {
    all().iter().find(|p| p.name == name).map(Preset::material)
}

/// The bundle file: every fit of a run, as the presets ship them.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Bundle {
    /// Always [`BUNDLE_FORMAT`].
    pub format: String,
    /// What the fits were made from, for the record.
    pub source: String,
    /// One entry per material, in name order.
    pub materials: Vec<BundleEntry>,
}

/// One material of a [`Bundle`].
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BundleEntry {
    /// The material's name.
    pub name: String,
    /// Lobes kept.
    pub lobes: usize,
    /// The BRDF error of the fit with 1, 2, 3 lobes (those tried).
    pub brdf_error: Vec<f64>,
    /// The judge's image error (RMSE over peak) of each, if judged.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub image_error: Vec<f64>,
    /// The 108 control points.
    pub ctrl: Vec<f64>,
}

/// The bundle format's name.
pub const BUNDLE_FORMAT: &str = "matedit-fits-1";

impl Bundle {
    /// Parses a bundle's text; the error names the item.
    pub fn parse(text: &str) -> std::result::Result<Self, String> {
        let b: Bundle =
            serde_json::from_str(text).map_err(|e| format!("not a fits bundle: {e}"))?;
        if b.format != BUNDLE_FORMAT {
            return Err(format!(
                "format is '{}'; expected '{BUNDLE_FORMAT}'",
                b.format
            ));
        }
        for m in &b.materials {
            material_from_ctrl(m.name.clone(), &m.ctrl)
                .map_err(|e| format!("material '{}': {e}", m.name))?;
        }
        Ok(b)
    }

    /// The materials.
    pub fn materials(&self) -> Vec<Material> {
        self.materials
            .iter()
            .map(|m| Material::new(m.name.clone(), &m.ctrl).expect("checked by parse"))
            .collect()
    }

    /// Pretty JSON, one number a line.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = serde_json::to_vec_pretty(self).unwrap_or_default();
        out.push(b'\n');
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_are_valid_and_default_exists() {
        assert!(lookup(DEFAULT).is_some());
        assert_eq!(all()[0].name, DEFAULT);
        for p in all() {
            let m = p.material();
            Material::new(p.name, &m.ctrl).unwrap();
        }
        let names = names();
        assert!(names.len() >= 95, "{} presets", names.len());
        let mut unique = names.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), names.len(), "preset names repeat");
    }

    #[test]
    fn lambert_scale_matches_albedo() {
        let m0 = lambert([0.8; 3]).m0[0];
        assert!((m0.exp_m1() - 0.8 / std::f64::consts::PI).abs() < 1e-3);
    }
}
