//! Batch manifests (`render --batch`): parsed, as the command line does before it turns
//! one into a plan (the command line's own unit tests check that step).
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use matedit::io;
use matedit_fuzz::clean;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz/batch.json");
    clean(path, io::manifest::parse(path, data, None));
});
