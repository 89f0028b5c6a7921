//! NumPy `.npy` arrays: the parser, then the array as a raster (as normals, env maps and
//! images are read).
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use matedit::io;
use matedit_fuzz::{clean, clean_message};

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz/in.npy");
    if let Some(a) = clean_message(path, io::npy::parse(data)) {
        assert_eq!(a.data.len(), a.shape.iter().product::<usize>());
    }
    clean(path, io::raster_from_bytes(path, data, "a raster"));
});
