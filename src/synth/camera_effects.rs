//! Camera effects (`"camera_effects"` of a synth spec): a composed sample developed as a
//! camera writes a photo, then read back as the edit pipeline reads a JPEG photo, so that
//! networks train on what they will be given.
//!
//! Per sample, in this order: exposure (a gain that puts the frame's mean luminance at
//! [`MIDDLE_GREY`], times 2^stops; the sample's light is scaled by the same gain, so that
//! the image stays the render of its light) -> defocus (the background
//! layer blurred by a Gaussian, the object kept sharp) -> vignette (a radial fall-off) ->
//! noise (read noise and shot noise) -> 8-bit sRGB (a plain clip to [0, 1], as
//! [`display_value`] does) -> JPEG encoded and decoded at a drawn quality (if asked) ->
//! linear float32 (`srgb_decode(i / 255)`, as photos are read). Every draw comes from the
//! sample's camera-effects generator, recorded in its params.

use serde::Deserialize;
use serde_json::{Map, Value, json};

use crate::error::Result;
use crate::io::png::{Preview, display_value, srgb_decode};
use crate::scene::Image;
use crate::splitmix::SplitMix;

/// The frame's mean luminance after an exposure of 0 stops: a camera's automatic exposure
/// puts the mean at about middle grey.
pub const MIDDLE_GREY: f64 = 0.18;

/// Largest defocus sigma, pixels (the blur's radius is 3 sigma).
pub const MAX_DEFOCUS: f64 = 64.0;

/// Largest exposure either way, stops.
pub const MAX_EXPOSURE: f64 = 20.0;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Raw {
    exposure: Option<[f64; 2]>,
    noise: Option<[f64; 2]>,
    jpeg: Option<[i64; 2]>,
    defocus: Option<[f64; 2]>,
    vignette: Option<[f64; 2]>,
}

/// The ranges each sample's camera draws from; an absent range is an effect left off.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CameraEffects {
    /// Exposure, stops, uniform.
    pub exposure: Option<[f64; 2]>,
    /// Noise level, uniform: the read noise's standard deviation as a fraction of the
    /// image's mean; the shot noise has that deviation where the signal is the mean.
    pub noise: Option<[f64; 2]>,
    /// JPEG quality, integers uniform (absent: no JPEG, the 8-bit image as it is).
    pub jpeg: Option<[u8; 2]>,
    /// Defocus of the background: a Gaussian's sigma in pixels, uniform.
    pub defocus: Option<[f64; 2]>,
    /// Vignette strength, uniform: the gain falls as 1 - v (r / r_corner)^2.
    pub vignette: Option<[f64; 2]>,
}

/// One sample's draws.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EffectDraws {
    /// Exposure, stops.
    pub exposure_stops: Option<f64>,
    /// Sigma of the background's blur, pixels.
    pub defocus_sigma: Option<f64>,
    /// Vignette strength.
    pub vignette: Option<f64>,
    /// Noise level (fraction of the image's mean).
    pub noise_level: Option<f64>,
    /// Seed of the noise field (shared by every image of the sample: the edit's too).
    pub noise_seed: Option<u64>,
    /// JPEG quality.
    pub jpeg_quality: Option<u8>,
}

impl CameraEffects {
    /// The spec's `camera_effects` object, checked; errors name the key
    /// (`camera_effects.jpeg: [95, 20]: expected LO <= HI`).
    pub fn parse(v: &Value) -> std::result::Result<CameraEffects, String> {
        let raw: Raw = serde_path_to_error::deserialize(v.clone()).map_err(|e| {
            let at = e.path().to_string();
            let m = super::sources::serde_message(e.inner());
            if at == "." {
                format!("camera_effects: {m}")
            } else {
                format!("camera_effects.{at}: {m}")
            }
        })?;
        let jpeg = range(
            "jpeg",
            raw.jpeg.map(|r| r.map(|q| q as f64)),
            1.0,
            100.0,
            "qualities in 1..=100",
        )?;
        Ok(CameraEffects {
            exposure: range(
                "exposure",
                raw.exposure,
                -MAX_EXPOSURE,
                MAX_EXPOSURE,
                "stops within [-20, 20]",
            )?,
            noise: range("noise", raw.noise, 0.0, f64::MAX, "levels >= 0")?,
            jpeg: jpeg.map(|r| r.map(|q| q as u8)),
            defocus: range(
                "defocus",
                raw.defocus,
                0.0,
                MAX_DEFOCUS,
                "sigmas within [0, 64] pixels",
            )?,
            vignette: range(
                "vignette",
                raw.vignette,
                0.0,
                1.0,
                "strengths within [0, 1]",
            )?,
        })
    }

    /// One sample's draws from `rng`, in a fixed order (exposure, defocus, vignette,
    /// noise level and seed, JPEG quality), each only if its range is given.
    pub fn draw(&self, rng: &mut SplitMix) -> EffectDraws {
        let mut uniform = |r: Option<[f64; 2]>| r.map(|[lo, hi]| lo + (hi - lo) * rng.uniform());
        let exposure_stops = uniform(self.exposure);
        let defocus_sigma = uniform(self.defocus);
        let vignette = uniform(self.vignette);
        let noise_level = uniform(self.noise);
        let noise_seed = self.noise.map(|_| rng.next_u64());
        let jpeg_quality = self
            .jpeg
            .map(|[lo, hi]| lo + rng.below(usize::from(hi - lo) + 1) as u8);
        EffectDraws {
            exposure_stops,
            defocus_sigma,
            vignette,
            noise_level,
            noise_seed,
            jpeg_quality,
        }
    }
}

/// `r` checked: LO <= HI, both within [min, max].
fn range(
    key: &str,
    r: Option<[f64; 2]>,
    min: f64,
    max: f64,
    what: &str,
) -> std::result::Result<Option<[f64; 2]>, String> {
    let Some([lo, hi]) = r else { return Ok(None) };
    if lo > hi || lo.is_nan() || hi.is_nan() {
        return Err(format!(
            "camera_effects.{key}: [{lo}, {hi}]: expected LO <= HI"
        ));
    }
    if !(lo >= min && hi <= max) {
        return Err(format!(
            "camera_effects.{key}: [{lo}, {hi}]: expected {what}"
        ));
    }
    Ok(Some([lo, hi]))
}

impl EffectDraws {
    /// What the sample's params record of the draws.
    pub fn record(&self) -> Value {
        let mut o = Map::new();
        let mut put = |k: &str, v: Option<Value>| {
            if let Some(v) = v {
                o.insert(k.into(), v);
            }
        };
        put("exposure_stops", self.exposure_stops.map(|v| json!(v)));
        put("defocus_sigma", self.defocus_sigma.map(|v| json!(v)));
        put("vignette", self.vignette.map(|v| json!(v)));
        put("noise_level", self.noise_level.map(|v| json!(v)));
        put("noise_seed", self.noise_seed.map(|v| json!(v)));
        put("jpeg_quality", self.jpeg_quality.map(|v| json!(v)));
        put("clip", Some(json!("plain")));
        Value::Object(o)
    }

    /// Develops `images` in place: the sample's composed image first, then any other
    /// image of the same scene (the edit), all with these draws, the first image's mean
    /// and one noise field, so that they differ only where their pixels did.
    /// `background` (the layer behind the object, `None`: black) and `mask` (the object)
    /// are the sample's. Returns the read noise's standard deviation (linear units) and
    /// the exposure's gain, by which the caller scales the sample's light.
    pub fn develop(
        &self,
        images: &mut [Image],
        background: Option<&[[f32; 3]]>,
        mask: &[bool],
    ) -> Result<(f64, f64)> {
        let Some(first) = images.first() else {
            return Ok((0.0, 1.0));
        };
        let mean = first
            .pixels
            .iter()
            .map(|p| crate::envgen::colour::luminance(p.map(f64::from)))
            .sum::<f64>()
            / first.pixels.len().max(1) as f64;
        // a black frame keeps its level; the gain stays within 1e-4..1e4
        let auto = if mean > 1e-12 {
            (MIDDLE_GREY / mean).clamp(1e-4, 1e4)
        } else {
            1.0
        };
        let gain = auto * self.exposure_stops.unwrap_or(0.0).exp2();
        let (w, h) = (first.width, first.height);
        if let (Some(bg), Some(sigma)) = (background, self.defocus_sigma)
            && sigma > 0.0
        {
            let mut blurred = bg.to_vec();
            crate::raster::gaussian_blur(&mut blurred, w, h, sigma);
            for im in images.iter_mut() {
                for ((p, b), m) in im.pixels.iter_mut().zip(&blurred).zip(mask) {
                    if !m {
                        *p = *b;
                    }
                }
            }
        }
        let v = self.vignette.unwrap_or(0.0);
        if gain != 1.0 || v != 0.0 {
            let (cx, cy) = (w as f64 / 2.0, h as f64 / 2.0);
            let corner = cx * cx + cy * cy;
            for im in images.iter_mut() {
                for (i, p) in im.pixels.iter_mut().enumerate() {
                    let x = (i % w) as f64 + 0.5 - cx;
                    let y = (i / w) as f64 + 0.5 - cy;
                    let g = (gain * (1.0 - v * (x * x + y * y) / corner)) as f32;
                    *p = p.map(|c| c * g);
                }
            }
        }
        let read_std = self.add_noise(images);
        for im in images.iter_mut() {
            let rgb: Vec<u8> = im
                .pixels
                .iter()
                .flat_map(|p| p.map(|c| display_value(c, &Preview::default())))
                .collect();
            let rgb = match self.jpeg_quality {
                Some(q) => crate::io::jpeg::round_trip(&rgb, w, h, q)?,
                None => rgb,
            };
            let table = srgb8_table();
            for (p, c) in im.pixels.iter_mut().zip(rgb.chunks_exact(3)) {
                *p = [
                    table[c[0] as usize],
                    table[c[1] as usize],
                    table[c[2] as usize],
                ];
            }
        }
        Ok((read_std, gain))
    }

    /// Read and shot noise from one field of standard normals: value x becomes
    /// x + sqrt(s^2 + s m x) z with s = level m, m the first image's mean.
    fn add_noise(&self, images: &mut [Image]) -> f64 {
        let (Some(level), Some(seed)) = (self.noise_level, self.noise_seed) else {
            return 0.0;
        };
        let n = images[0].pixels.len() * 3;
        let mean = images[0]
            .pixels
            .iter()
            .flatten()
            .map(|&c| f64::from(c))
            .sum::<f64>()
            / n.max(1) as f64;
        let read = level * mean.max(0.0);
        if read <= 0.0 || !read.is_finite() {
            return 0.0;
        }
        let shot = level * read; // variance per unit of signal: s m
        let z = SplitMix(seed).standard_normals(n);
        for im in images.iter_mut() {
            for (c, z) in im.pixels.iter_mut().flatten().zip(&z) {
                let x = f64::from(*c);
                *c = (x + (read * read + shot * x.max(0.0)).sqrt() * z) as f32;
            }
        }
        read
    }
}

/// The linear value of each 8-bit sRGB code: `srgb_decode(i / 255)`, as photos are read.
pub fn srgb8_table() -> [f32; 256] {
    std::array::from_fn(|i| srgb_decode(i as f32 / 255.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> std::result::Result<CameraEffects, String> {
        CameraEffects::parse(&serde_json::from_str(s).unwrap())
    }

    #[test]
    fn bad_ranges_are_refused_naming_the_key() {
        for (spec, expect) in [
            (
                r#"{"jpeg": [95, 20]}"#,
                "camera_effects.jpeg: [95, 20]: expected LO <= HI",
            ),
            (
                r#"{"jpeg": [0, 20]}"#,
                "camera_effects.jpeg: [0, 20]: expected qualities in 1..=100",
            ),
            (
                r#"{"jpeg": [90, 101]}"#,
                "camera_effects.jpeg: [90, 101]: expected qualities",
            ),
            (
                r#"{"noise": [-0.1, 0.2]}"#,
                "camera_effects.noise: [-0.1, 0.2]: expected levels >= 0",
            ),
            (
                r#"{"defocus": [-1, 2]}"#,
                "camera_effects.defocus: [-1, 2]: expected sigmas",
            ),
            (
                r#"{"exposure": [1, -1]}"#,
                "camera_effects.exposure: [1, -1]: expected LO <= HI",
            ),
            (
                r#"{"vignette": [0, 2]}"#,
                "camera_effects.vignette: [0, 2]: expected strengths",
            ),
            (
                r#"{"blur": [0, 2]}"#,
                "camera_effects.blur: unknown field `blur`",
            ),
            (r#"{"jpeg": 90}"#, "camera_effects.jpeg: invalid type"),
        ] {
            let e = parse(spec).unwrap_err();
            assert!(e.starts_with(expect) && !e.contains('\n'), "{spec}: {e}");
        }
        assert_eq!(parse("{}").unwrap(), CameraEffects::default());
    }

    #[test]
    fn draws_stay_in_their_ranges_and_record_themselves() {
        let fx = parse(
            r#"{"exposure": [-1, 1], "noise": [0, 0.05], "jpeg": [30, 31], "defocus": [1, 2],
                "vignette": [0.2, 0.2]}"#,
        )
        .unwrap();
        let mut rng = SplitMix(5);
        let mut qualities = std::collections::BTreeSet::new();
        for _ in 0..200 {
            let d = fx.draw(&mut rng);
            assert!((-1.0..1.0).contains(&d.exposure_stops.unwrap()));
            assert!((1.0..2.0).contains(&d.defocus_sigma.unwrap()));
            assert_eq!(d.vignette, Some(0.2));
            qualities.insert(d.jpeg_quality.unwrap());
        }
        assert_eq!(qualities.into_iter().collect::<Vec<_>>(), [30, 31]);
        let r = fx.draw(&mut SplitMix(1)).record();
        for k in [
            "exposure_stops",
            "defocus_sigma",
            "vignette",
            "noise_level",
            "noise_seed",
            "jpeg_quality",
        ] {
            assert!(r.get(k).is_some(), "{k}: {r}");
        }
        let none = CameraEffects::default().draw(&mut SplitMix(1)).record();
        assert_eq!(none, json!({"clip": "plain"}));
    }

    fn ramp(w: usize, h: usize) -> Image {
        Image {
            width: w,
            height: h,
            pixels: (0..w * h)
                .map(|i| [i as f32 / (w * h) as f32 * 1.2, 0.3, 0.05 * (i % 7) as f32])
                .collect(),
        }
    }

    #[test]
    fn jpeg_quality_changes_the_pixels_and_stays_on_the_8_bit_grid() {
        let im = ramp(32, 32);
        let mask = vec![false; 32 * 32];
        let dev = |q: u8| {
            let d = EffectDraws {
                jpeg_quality: Some(q),
                ..EffectDraws::default()
            };
            let mut out = [im.clone()];
            d.develop(&mut out, None, &mask).unwrap();
            out[0].pixels.clone()
        };
        let (lo, hi) = (dev(10), dev(95));
        assert_ne!(lo, hi);
        assert_eq!(dev(10), lo, "the same quality, the same pixels");
        let table = srgb8_table();
        assert!(lo.iter().flatten().all(|v| table.contains(v)));
    }

    /// The automatic exposure's gain: the mean luminance to middle grey.
    fn auto_gain(im: &Image) -> f64 {
        let lum: f64 = im
            .pixels
            .iter()
            .map(|p| crate::envgen::colour::luminance(p.map(f64::from)))
            .sum();
        MIDDLE_GREY / (lum / im.pixels.len() as f64)
    }

    #[test]
    fn noise_is_shared_and_scales_with_its_level() {
        let im = ramp(32, 32);
        let mask = vec![false; 32 * 32];
        let d = EffectDraws {
            noise_level: Some(0.1),
            noise_seed: Some(9),
            ..EffectDraws::default()
        };
        let mut two = [im.clone(), im.clone()];
        let (read, gain) = d.develop(&mut two, None, &mask).unwrap();
        assert_eq!(two[0].pixels, two[1].pixels);
        assert!((gain - auto_gain(&im)).abs() < 1e-12 * gain);
        let mean = im
            .pixels
            .iter()
            .flatten()
            .map(|&c| f64::from(c * gain as f32))
            .sum::<f64>()
            / (32.0 * 32.0 * 3.0);
        assert!((read - 0.1 * mean).abs() < 1e-7, "{read} {mean}");
        assert_ne!(
            two[0].pixels,
            [im.clone()].map(|mut i| {
                EffectDraws::default()
                    .develop(std::slice::from_mut(&mut i), None, &mask)
                    .unwrap();
                i
            })[0]
                .pixels
        );
        let z = SplitMix(1).standard_normals(20001);
        let m = z.iter().sum::<f64>() / z.len() as f64;
        let v = z.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / z.len() as f64;
        assert!(m.abs() < 0.03 && (v - 1.0).abs() < 0.05, "{m} {v}");
    }

    #[test]
    fn defocus_blurs_the_background_only() {
        let (w, h) = (16, 16);
        let bg: Vec<[f32; 3]> = (0..w * h)
            .map(|i| if i % 2 == 0 { [0.8; 3] } else { [0.0; 3] })
            .collect();
        let mask: Vec<bool> = (0..w * h).map(|i| i / w < 4).collect();
        let mut im = Image {
            width: w,
            height: h,
            pixels: bg.clone(),
        };
        for (p, m) in im.pixels.iter_mut().zip(&mask) {
            if *m {
                *p = [0.5, 0.1, 0.9];
            }
        }
        let d = EffectDraws {
            defocus_sigma: Some(2.0),
            ..EffectDraws::default()
        };
        let gain = auto_gain(&im) as f32;
        let mut out = [im];
        d.develop(&mut out, Some(&bg), &mask).unwrap();
        let table = srgb8_table();
        let code = |v: f32| table.iter().position(|t| *t == v).unwrap() as i32;
        // the object is kept (8-bit), the stripes are blurred to their mean
        assert_eq!(
            out[0].pixels[0],
            [0.5, 0.1, 0.9].map(|c| table[display_value(c * gain, &Preview::default()) as usize])
        );
        let mid = out[0].pixels[10 * w + 8][0];
        let want = i32::from(display_value(0.4 * gain, &Preview::default()));
        assert!((code(mid) - want).abs() <= 1, "{mid}");
    }
}
