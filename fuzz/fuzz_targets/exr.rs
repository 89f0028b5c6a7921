//! OpenEXR files: channels R, G, B of the first layer as a raster.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use matedit::io;
use matedit_fuzz::clean;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz/in.exr");
    if let Some(r) = clean(path, io::exr::decode_rgb(path, data)) {
        assert_eq!(r.pixels.len(), r.width * r.height);
    }
});
