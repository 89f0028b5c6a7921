//! PNG files: decoded as images and masks are, and as a normal map.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use matedit::io;
use matedit_fuzz::clean;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz/in.png");
    if let Some(d) = clean(path, io::png::decode_bytes(path, data)) {
        assert_eq!(d.samples.len(), d.width * d.height * d.channels);
    }
    clean(path, io::normals_from_bytes(path, data));
});
