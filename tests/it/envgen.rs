//! The procedural lights (`matedit::envgen`): determinism, what each model must show (the
//! sun where it was placed with the same power at every size, a sky bluer than its sun,
//! the CIE overcast gradation, studio lights that hold the energy, a bright window), every
//! kind rendered through the layer, and the augmentations (turns, exposure, white balance).

use matedit::envgen::colour::luminance;
use matedit::envgen::raster::{direction, texel_of};
use matedit::envgen::sky::{Overcast, SUN_RADIUS, SunSky};
use matedit::envgen::{self, LightKind, Params, WhiteBalance};
use matedit::{Batch, Camera, Convention, Device, EnvMap, Material, NormalMap, Renderer, Scene};

fn power(e: &EnvMap) -> [f64; 3] {
    let mut sum = [0.0; 3];
    for (i, t) in e.texels.iter().enumerate() {
        let d = e
            .convention
            .texel(i / e.width, i % e.width, e.height, e.width)
            .1;
        for k in 0..3 {
            sum[k] += t[k] as f64 * d;
        }
    }
    sum
}

fn lum(t: [f32; 3]) -> f64 {
    luminance(t.map(f64::from))
}

fn brightest(e: &EnvMap) -> usize {
    (0..e.texels.len())
        .max_by(|&a, &b| lum(e.texels[a]).total_cmp(&lum(e.texels[b])))
        .unwrap()
}

fn median_luminance(e: &EnvMap) -> f64 {
    let mut l: Vec<f64> = e.texels.iter().map(|&t| lum(t)).collect();
    l.sort_by(f64::total_cmp);
    l[l.len() / 2]
}

fn sky(elevation: f64, azimuth: f64, turbidity: f64) -> SunSky {
    SunSky {
        elevation,
        azimuth,
        turbidity,
        ground: [0.2; 3],
        sun: true,
    }
}

#[test]
fn same_seed_same_map_other_seed_other_map() {
    for kind in LightKind::ALL {
        let a = envgen::generate(kind, 3, 16, 32).unwrap();
        let b = envgen::generate(kind, 3, 16, 32).unwrap();
        let c = envgen::generate(kind, 4, 16, 32).unwrap();
        assert_eq!(a, b, "{kind}");
        assert_ne!(a, c, "{kind}: seeds 3 and 4 gave the same map");
    }
}

#[test]
fn every_kind_finite_non_negative_at_any_size() {
    for kind in LightKind::ALL {
        for seed in 0..6 {
            for (h, w) in [(1, 2), (7, 13), (32, 64)] {
                let e = envgen::generate(kind, seed, h, w).unwrap();
                assert_eq!(
                    (e.height, e.width, e.convention),
                    (h, w, Convention::Equirect)
                );
                assert!(
                    e.texels
                        .iter()
                        .flatten()
                        .all(|v| v.is_finite() && *v >= 0.0),
                    "{kind} seed {seed} {h}x{w}"
                );
                assert!(power(&e)[1] > 0.0, "{kind} seed {seed} {h}x{w}: dark");
            }
        }
    }
    assert!(envgen::generate(LightKind::Studio, 0, 0, 8).is_err());
}

#[test]
fn sun_is_the_brightest_texel_where_it_was_placed() {
    for (elevation, azimuth) in [(30.0, 100.0), (75.0, 300.0), (1.0, 200.0), (8.0, 10.0)] {
        for (h, w) in [(32, 64), (128, 256)] {
            let e = sky(elevation, azimuth, 3.0).env(h, w).unwrap();
            let sun = direction(f64::to_radians(elevation), f64::to_radians(azimuth));
            assert_eq!(
                brightest(&e),
                texel_of(sun, h, w),
                "sun at {elevation}, {azimuth} on {h}x{w}"
            );
        }
    }
}

#[test]
fn sun_power_is_the_same_at_every_size() {
    let expected = |s: &SunSky| {
        let disc = s.model().unwrap().sun_disc();
        let omega = 2.0 * std::f64::consts::PI * (1.0 - SUN_RADIUS.cos());
        assert!((disc.solid_angle() - omega).abs() < 1e-15);
        disc.power()
    };
    for (elevation, turbidity) in [(45.0, 2.5), (5.0, 6.0)] {
        let with = sky(elevation, 123.0, turbidity);
        let without = SunSky { sun: false, ..with };
        let want = expected(&with);
        for (h, w) in [(32, 64), (256, 512)] {
            let (a, b) = (
                power(&with.env(h, w).unwrap()),
                power(&without.env(h, w).unwrap()),
            );
            for k in 0..3 {
                let p = a[k] - b[k];
                // the disc's power is placed exactly; the rest is f32 rounding of the sky
                assert!(
                    (p - want[k]).abs() < 0.01 * want[k],
                    "elevation {elevation}, {h}x{w}, channel {k}: {p} vs {}",
                    want[k]
                );
            }
        }
    }
}

#[test]
fn sun_on_the_horizon_shows_half_its_disc() {
    let with = sky(0.0, 40.0, 3.0);
    let without = SunSky { sun: false, ..with };
    let want = with.model().unwrap().sun_disc().power()[0] / 2.0;
    for (h, w) in [(32, 64), (256, 512)] {
        let p = power(&with.env(h, w).unwrap())[0] - power(&without.env(h, w).unwrap())[0];
        // 4096 points, half of them above the horizon to within a point or two
        assert!((p / want - 1.0).abs() < 2e-3, "{h}x{w}: {p} vs {want}");
    }
}

#[test]
fn sun_to_sky_illuminance_is_realistic() {
    let clear = sky(60.0, 0.0, 2.5).model().unwrap().sun_to_sky();
    let hazy = sky(60.0, 0.0, 8.0).model().unwrap().sun_to_sky();
    let low = sky(5.0, 0.0, 2.5).model().unwrap().sun_to_sky();
    let zenith = sky(90.0, 0.0, 2.0).model().unwrap().sun_to_sky();
    assert!((3.0..12.0).contains(&clear), "clear high sun: {clear}");
    assert!(
        (5.0..12.0).contains(&zenith),
        "clear sun at the zenith: {zenith}"
    );
    assert!(hazy < 0.7 * clear, "hazy {hazy} vs clear {clear}");
    assert!(
        low < 0.5 * clear && low > 0.0,
        "low sun {low} vs high {clear}"
    );
}

#[test]
fn sky_is_bluer_than_its_sun_and_low_suns_are_red() {
    for (elevation, turbidity) in [(60.0, 2.0), (20.0, 4.0), (3.0, 3.0)] {
        let s = sky(elevation, 0.0, turbidity);
        let m = s.model().unwrap();
        let sun = m.sun_disc().radiance;
        let zenith = m.radiance([0.0, 1.0, 0.0]);
        assert!(
            zenith[2] / zenith[0] > sun[2] / sun[0],
            "elevation {elevation}: zenith {zenith:?}, sun {sun:?}"
        );
    }
    let high = sky(60.0, 0.0, 3.0).model().unwrap().sun_disc().radiance;
    let low = sky(3.0, 0.0, 3.0).model().unwrap().sun_disc().radiance;
    assert!(
        low[2] / low[0] < 0.5 * high[2] / high[0],
        "{low:?} vs {high:?}"
    );
}

#[test]
fn clear_sky_brightens_towards_the_horizon_and_around_the_sun() {
    // Preetham's clear skies: opposite the sun the horizon is brighter than the zenith,
    // and the sky is brightest around the sun
    let m = sky(30.0, 0.0, 2.5).model().unwrap();
    let away = std::f64::consts::PI;
    let horizon = luminance(m.radiance(direction(2f64.to_radians(), away)));
    let zenith = luminance(m.radiance([0.0, 1.0, 0.0]));
    let near_sun = luminance(m.radiance(direction(25f64.to_radians(), 0.0)));
    assert!(horizon > 1.5 * zenith, "horizon {horizon}, zenith {zenith}");
    assert!(
        near_sun > 4.0 * zenith,
        "near the sun {near_sun}, zenith {zenith}"
    );
    // of order 1 after scaling
    assert!((0.1..10.0).contains(&zenith), "{zenith}");
}

#[test]
fn ground_is_lit_by_sky_and_sun() {
    // a Lambertian ground: radiance = albedo x (the map's horizontal illuminance) / pi
    let (h, w) = (64, 128);
    for seed in 0..8 {
        let Params::SunSky(p) = Params::draw(LightKind::SunSky, seed) else {
            unreachable!()
        };
        let e = p.env(h, w).unwrap();
        let mut irradiance = [0.0; 3];
        for (i, t) in e.texels[..h / 2 * w].iter().enumerate() {
            let (dir, d) = Convention::Equirect.texel(i / w, i % w, h, w);
            for (sum, v) in irradiance.iter_mut().zip(t) {
                *sum += *v as f64 * dir[1] * d;
            }
        }
        let ground = e.texels[(h - 1) * w];
        for k in 0..3 {
            let want = p.ground[k] * irradiance[k] / std::f64::consts::PI;
            // the map's quadrature of the illuminance against the model's: 2%
            assert!(
                (ground[k] as f64 / want - 1.0).abs() < 0.02,
                "seed {seed} channel {k}: ground {} vs {want}",
                ground[k]
            );
        }
        assert!(
            p.ground.iter().all(|a| (0.03..0.25).contains(a)),
            "{:?}",
            p.ground
        );
    }
}

#[test]
fn overcast_zenith_is_three_times_the_horizon() {
    let o = Overcast {
        tint: [1.0; 3],
        ground: [0.2; 3],
    };
    let ratio = luminance(o.radiance([0.0, 1.0, 0.0])) / luminance(o.radiance([1.0, 0.0, 0.0]));
    assert!((ratio - 3.0).abs() < 1e-12, "{ratio}");
    let (h, w) = (64, 128);
    let e = o.env(h, w).unwrap();
    // the map's top row against the row just above the horizon, by the formula at the
    // rows' centres (the mean over a texel of a function linear in sin(elevation))
    let elev =
        |r: usize| std::f64::consts::FRAC_PI_2 - (r as f64 + 0.5) / h as f64 * std::f64::consts::PI;
    let want = (1.0 + 2.0 * elev(0).sin()) / (1.0 + 2.0 * elev(h / 2 - 1).sin());
    let got = lum(e.texels[0]) / lum(e.texels[(h / 2 - 1) * w]);
    assert!((got / want - 1.0).abs() < 2e-3, "{got} vs {want}");
    assert!(want > 2.8);
}

#[test]
fn studio_lights_hold_most_of_the_energy() {
    for seed in 0..16 {
        let e = envgen::generate(LightKind::Studio, seed, 64, 128).unwrap();
        let median = median_luminance(&e);
        let total = luminance(power(&e));
        let bright: f64 = e
            .texels
            .iter()
            .enumerate()
            .filter(|(_, t)| lum(**t) > 5.0 * median)
            .map(|(i, t)| lum(*t) * Convention::Equirect.texel(i / 128, i % 128, 64, 128).1)
            .sum();
        assert!(
            bright > 0.6 * total,
            "seed {seed}: lights {bright} of {total}"
        );
        let peak = lum(e.texels[brightest(&e)]);
        assert!(
            peak > 10.0 * median,
            "seed {seed}: peak {peak}, median {median}"
        );
    }
}

#[test]
fn indoor_window_is_brighter_than_the_wall_beside_it() {
    for seed in 0..12 {
        let Params::Indoor(room) = Params::draw(LightKind::Indoor, seed) else {
            unreachable!()
        };
        let e = room.env(64, 128).unwrap();
        let ((c, hw), (b, t)) = room.window;
        let wall = room.window_wall;
        let plane = [room.max[0], room.min[0], room.max[2], room.min[2]][wall];
        let axis = if wall < 2 { 2 } else { 0 };
        // the wall 0.1 m beyond the window's edge, on the side with room to spare
        let beside = if c + hw + 0.1 < room.max[axis] {
            c + hw + 0.1
        } else {
            c - hw - 0.1
        };
        let at = |u: f64| {
            let p = if wall < 2 {
                [plane, (b + t) / 2.0, u]
            } else {
                [u, (b + t) / 2.0, plane]
            };
            let l = p.iter().map(|v| v * v).sum::<f64>().sqrt();
            lum(e.texels[texel_of(p.map(|v| v / l), 64, 128)])
        };
        let (window, next) = (at(c), at(beside));
        assert!(
            window > 2.0 * next,
            "seed {seed}: window {window}, wall {next}"
        );
        assert!(window > median_luminance(&e), "seed {seed}");
    }
}

#[test]
fn every_kind_renders_a_sphere() {
    let renderer = Renderer::new(Device::Cpu).unwrap();
    let material = Material::constant("plastic", [(0.5, 0.0), (2.0, 50.0), (0.0, 0.0)]).unwrap();
    for kind in LightKind::ALL {
        let scene = Scene {
            normals: NormalMap::sphere(16),
            env: envgen::generate(kind, 1, 16, 32).unwrap(),
            material: material.clone(),
            camera: Camera::Orthographic,
        };
        let image = &renderer.render(&Batch::single(scene).unwrap()).unwrap()[0];
        assert!(
            image
                .pixels
                .iter()
                .flatten()
                .all(|v| v.is_finite() && *v >= 0.0)
        );
        assert!(image.pixels.iter().any(|p| p[1] > 0.0), "{kind}: black");
    }
}

/// A map with a different value in every texel and channel.
fn ramp(h: usize, w: usize) -> EnvMap {
    let texels = (0..h * w)
        .map(|i| [i as f32, ((i * 7) % 11) as f32, 1.0 + (i % 3) as f32])
        .collect();
    EnvMap::new(h, w, Convention::Equirect, texels).unwrap()
}

#[test]
fn whole_column_turn_is_a_roll() {
    let (h, w) = (4, 16);
    let e = ramp(h, w);
    for k in [0usize, 1, 5, 15, 16, 21] {
        let t = envgen::turn(&e, 360.0 / w as f64 * k as f64).unwrap();
        for r in 0..h {
            for c in 0..w {
                assert_eq!(t.texels[r * w + (c + k) % w], e.texels[r * w + c], "k {k}");
            }
        }
    }
    assert_eq!(envgen::turn(&e, -360.0).unwrap(), e);
}

#[test]
fn turn_keeps_power_and_composes() {
    let e = envgen::generate(LightKind::SunSky, 2, 32, 64).unwrap();
    let p0 = power(&e);
    for deg in [17.3, -123.45, 0.01, 359.9] {
        let p = power(&envgen::turn(&e, deg).unwrap());
        for k in 0..3 {
            assert!((p[k] / p0[k] - 1.0).abs() < 1e-3, "{deg}: {p:?} vs {p0:?}");
        }
    }
    // a fractional turn and a whole-column one: the same weights, so the same map
    let col = 360.0 / 64.0;
    let a = envgen::turn(&envgen::turn(&e, 10.0).unwrap(), 3.0 * col).unwrap();
    let b = envgen::turn(&e, 10.0 + 3.0 * col).unwrap();
    for (x, y) in a.texels.iter().flatten().zip(b.texels.iter().flatten()) {
        assert!((x - y).abs() <= 1e-5 * y.abs().max(1.0), "{x} vs {y}");
    }
    // two fractional turns move the light's centre of power by their sum
    let studio = envgen::generate(LightKind::Studio, 5, 32, 64).unwrap();
    let centre = |e: &EnvMap| {
        let (mut x, mut z) = (0.0, 0.0);
        for (i, t) in e.texels.iter().enumerate() {
            let (dir, d) = e
                .convention
                .texel(i / e.width, i % e.width, e.height, e.width);
            x += lum(*t) * d * dir[0];
            z += lum(*t) * d * dir[2];
        }
        z.atan2(x).to_degrees()
    };
    let twice = envgen::turn(&envgen::turn(&studio, 20.7).unwrap(), 33.9).unwrap();
    let moved = (centre(&twice) - centre(&studio)).rem_euclid(360.0);
    assert!((moved - 54.6).abs() < 0.5, "moved {moved}");
}

#[test]
fn turn_refuses_the_paper_convention_and_bad_angles() {
    let e = EnvMap::constant(4, 8, Convention::Paper, [1.0; 3]).unwrap();
    assert!(envgen::turn(&e, 10.0).is_err());
    assert!(envgen::turn(&ramp(4, 8), f64::NAN).is_err());
}

#[test]
fn exposure_scales_exactly() {
    let e = ramp(4, 8);
    let up = envgen::exposure(&e, 2.0).unwrap();
    let down = envgen::exposure(&e, -3.0).unwrap();
    for i in 0..e.texels.len() {
        for k in 0..3 {
            assert_eq!(up.texels[i][k], e.texels[i][k] * 4.0);
            assert_eq!(down.texels[i][k], e.texels[i][k] / 8.0);
        }
    }
    let half = envgen::exposure(&e, 0.5).unwrap();
    let p = power(&half)[0] / power(&e)[0];
    assert!((p - 2f64.sqrt()).abs() < 1e-6, "{p}");
    let big = EnvMap::constant(2, 4, Convention::Equirect, [1e10; 3]).unwrap();
    let err = envgen::exposure(&big, 20.0).unwrap_err().to_string();
    assert!(err.contains("largest radiance"), "{err}");
}

#[test]
fn white_balance_by_temperature_and_gains() {
    let d65 = WhiteBalance::Temperature(6500.0).gains().unwrap();
    assert!(d65.iter().all(|g| (g - 1.0).abs() < 1e-12), "{d65:?}");
    let warm = WhiteBalance::Temperature(3200.0).gains().unwrap();
    assert!(warm[0] > 1.0 && warm[2] < 0.8, "{warm:?}");
    assert!((luminance(warm) - 1.0).abs() < 1e-12);
    let e = ramp(2, 4);
    let g = envgen::white_balance(&e, WhiteBalance::Gains([2.0, 1.0, 0.5])).unwrap();
    for (a, b) in g.texels.iter().zip(&e.texels) {
        assert_eq!(*a, [b[0] * 2.0, b[1], b[2] * 0.5]);
    }
    assert!("3200K".parse::<WhiteBalance>().is_ok());
    assert!("1,1.1,0.9".parse::<WhiteBalance>().is_ok());
    for bad in ["1,2", "100K", "warm", "1,-1,1", "1,nan,1"] {
        assert!(bad.parse::<WhiteBalance>().is_err(), "{bad}");
    }
}

#[test]
fn bad_parameters_are_named() {
    let err = sky(95.0, 0.0, 3.0).env(8, 16).unwrap_err().to_string();
    assert!(err.contains("sun elevation") && err.contains("95"), "{err}");
    let err = sky(30.0, 0.0, 12.0).env(8, 16).unwrap_err().to_string();
    assert!(err.contains("turbidity"), "{err}");
    assert!("sunny".parse::<LightKind>().is_err());
    assert_eq!("indoor".parse::<LightKind>(), Ok(LightKind::Indoor));
}
