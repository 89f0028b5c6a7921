//! The layer bench's inputs: the env map and the scenes' normals.

use matedit::{EnvMap, NormalMap};

use crate::Opts;
use crate::common::{self, BUMPY_SEED};

/// The env map: a real HDR map resampled to `--env-size` (64 x 128), else the built-in sky.
pub fn load_env(opts: &Opts) -> (EnvMap, String) {
    let path = opts
        .env
        .clone()
        .or_else(|| common::envmap_files().into_iter().next());
    let Some(path) = path else {
        println!("env: no ../shared/data/envmaps/*.exr; using the built-in sky");
        return common::builtin_sky(opts.env_size);
    };
    match common::load_env_file(&path, opts.env_size) {
        Ok(l) => (l.env, l.desc),
        Err(e) => {
            println!("env: {e}; using the built-in sky");
            common::builtin_sky(opts.env_size)
        }
    }
}

/// The normals of a scene of `--scenes`.
pub fn normals_of(scene: &str) -> NormalMap {
    match scene {
        "sphere128" => NormalMap::sphere(128),
        "sphere256" => NormalMap::sphere(256),
        "sphere1024" => NormalMap::sphere(1024),
        "bumpy320x240" => NormalMap::bumpy(320, 240, BUMPY_SEED),
        _ => NormalMap::bumpy(256, 256, BUMPY_SEED),
    }
}
