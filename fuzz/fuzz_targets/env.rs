//! Environment maps as the command line loads them: the first byte picks the format (EXR
//! or NPY), the convention and the `--env-size`; the rest is the file. Loaded, checked,
//! negative texels clamped, then brought to the size.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use matedit::Convention;
use matedit::io::{self, EnvSize};
use matedit_fuzz::clean;

fuzz_target!(|data: &[u8]| {
    let Some((&pick, file)) = data.split_first() else {
        return;
    };
    let path = Path::new(if pick & 1 == 0 {
        "fuzz/env.exr"
    } else {
        "fuzz/env.npy"
    });
    let convention = if pick & 2 == 0 {
        Convention::Equirect
    } else {
        Convention::Paper
    };
    let size = match (pick >> 2) & 3 {
        0 => EnvSize::Full,
        1 => EnvSize::default(),
        2 => EnvSize::Size {
            height: 1,
            width: 1,
        },
        _ => EnvSize::Size {
            height: 2,
            width: 4,
        },
    };
    if let Some(loaded) = clean(path, io::env_from_bytes(path, file, convention)) {
        if let Some(env) = clean(path, io::resample::fit(loaded.env, size, path)) {
            assert!(env.validate().is_ok());
        }
    }
});
