//! matedit renders and differentiates the physically based rendering layer of Liu et al.,
//! "Material Editing Using a Physically Based Rendering Network" (ICCV 2017): per-pixel
//! normals lit by an HDR environment map through a Directional Statistics BRDF.
//!
//! Scenes, materials and environment maps are plain types ([`Scene`], [`Batch`],
//! [`Material`], [`EnvMap`]); a [`Renderer`] runs the forward pass ([`Renderer::render`])
//! and the vector-Jacobian product ([`Renderer::backward`]) on whichever backend it holds:
//! WGSL compute shaders through wgpu ([`gpu`]), the fast f32 SIMD CPU path ([`cpu`]) or
//! the f64 CPU reference ([`reference`](mod@reference)) that the other two are tested against.
//!
//! ```no_run
//! use matedit::{Batch, Camera, Device, EnvMap, Material, NormalMap, Renderer, Scene};
//! let scene = Scene {
//!     normals: NormalMap::sphere(64),
//!     env: EnvMap::constant(64, 128, Default::default(), [1.0; 3])?,
//!     material: Material::constant("plastic", [(0.5, 1.0), (2.0, 50.0), (0.0, 0.0)])?,
//!     camera: Camera::Orthographic,
//! };
//! let batch = Batch::single(scene)?;
//! let renderer = Renderer::new(Device::Auto)?;
//! let image = &renderer.render(&batch)?[0];
//! # Ok::<(), matedit::Error>(())
//! ```
//!
//! # Map
//!
//! Each layer uses only those beneath it (`tests/it/layout.rs` checks that no files and no
//! top-level modules import each other around a circle):
//!
//! - [`shapes`]: meshes and procedural shapes rasterised to normal maps (on the scene
//!   types);
//! - [`nets`]: the networks of `matedit.nets` (normals and mask, material, light) run on
//!   the CPU from their safetensors weights (on the scene types);
//! - what uses the renderer: [`edit`] (a material fitted to an image), [`synth`]
//!   (datasets), [`fit_brdf`] (the DSBRDF fitted to measured [`brdf`]s), [`io`] (files in and
//!   out), [`continuous_light`] (the continuous light);
//! - the renderer: [`Device`], [`Renderer`], [`Accuracy`];
//! - [`lod`]: levels of detail, on any backend;
//! - the backends: [`gpu`], [`cpu`], [`reference`](mod@reference);
//! - beneath them: the [`Backend`] trait over [`Scenes`], and [`prepare`] (prepared scenes);
//! - on images: [`raster`] (bilinear lookups, box filters, crops, blurs), [`segment`]
//!   (an object cut out of a photo from a box and points);
//! - scene types: [`scene`] (with the [`NormalMap`]), [`material`], [`envmap`], [`camera`];
//!   built-in inputs: [`presets`], [`builtin_sky`]; procedural lights: [`envgen`];
//! - at the bottom: [`error`], [`spline`], [`splitmix`].

#![allow(
    clippy::needless_range_loop,
    reason = "loops mirror the WGSL shaders index for index"
)]

mod backend;
pub mod brdf;
pub mod builtin_sky;
pub mod camera;
pub mod continuous_light;
pub mod cpu;
pub mod edit;
pub mod envgen;
pub mod envmap;
pub mod error;
pub mod fit_brdf;
pub mod gpu;
pub mod io;
pub mod lod;
pub mod material;
pub mod nets;
mod normals;
pub mod prepare;
pub mod presets;
pub mod raster;
pub mod reference;
mod renderer;
pub mod scene;
pub mod segment;
#[cfg(feature = "serve")]
pub mod serve;
pub mod shapes;
pub mod spline;
pub mod splitmix;
pub mod synth;

pub use backend::{Backend, Jacobian, PassTiming, Scenes};
pub use camera::Camera;
pub use envmap::{Convention, EnvMap};
pub use error::{Error, Result};
pub use material::{Material, N_PARAMS};
pub use renderer::{Accuracy, Device, Renderer};
pub use scene::{Batch, Gradients, Image, NormalMap, Scene, Wanted};
