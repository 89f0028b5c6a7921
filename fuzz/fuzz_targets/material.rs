//! Material JSON files (`{"name": ..., "ctrl": [108 numbers]}`).
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use matedit::io;
use matedit_fuzz::clean;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz/in.json");
    if let Some(m) = clean(path, io::json::parse_material(path, data)) {
        assert!(m.validate().is_ok());
    }
});
