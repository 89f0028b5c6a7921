//! Batch manifests (`render --batch`): parsed and turned into a plan, as the command line
//! does before loading the scenes' files.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use matedit::io::{self, job};
use matedit_fuzz::clean;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz/batch.json");
    if let Some(m) = clean(path, io::manifest::parse(path, data, None)) {
        let plan = job::Plan::from_manifest(&job::SceneOptions::default(), &m, None);
        assert_eq!(plan.scenes.len(), m.scenes.len());
    }
});
