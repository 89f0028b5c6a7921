//! Brute-force f64 rendering with any isotropic BRDF.
