//! matedit's integration tests, one binary (cargo's own layout): a module per area, sharing
//! the fixtures in `common`, the stability sweeps in `sweeps` and the HTTP client in `http`.
//! One suite stays a binary of its own: `tests/inputs_prop/` counts every allocation of its
//! process through a global allocator. The glTF cases of `shapes_files` need the `gltf`
//! feature (`.ci/run` builds everything with it, once).
//!
//! `cargo test --test it MODULE::` runs one area, e.g. `cargo test --test it backends::`.

mod common;
mod http;
mod sweeps;

// the command line, end to end
mod cli;
mod cli_env;
mod cli_normals;
// the layer on each backend against the f64 reference, and its gradients
mod backends;
mod cpu_math;
mod cpu_vs_reference;
mod gpu_bindings;
mod gpu_cache;
mod gpu_plan;
mod gpu_vs_reference;
mod gradcheck;
mod numerics;
mod shaders;
mod stability;
mod wanted;
// levels of detail and the continuous light
mod continuous_light;
mod lod;
// inputs: files, shapes, lights, validation
mod envgen;
mod io;
mod shapes;
mod shapes_files;
mod validation;
// what uses the layer: materials, editing, networks, datasets, the web editor
mod edit;
mod edit_known;
mod edit_photo;
mod fit;
mod measured;
mod nets;
mod photos;
mod pointing;
mod serve;
mod synth;
mod synth_photos;
// the source tree's rules
mod layout;
