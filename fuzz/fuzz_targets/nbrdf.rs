//! NBRDF network files (`{"format": "nbrdf-6-21-21-3", "materials": {...}}`): parsed as
//! `nbrdf::read` does after reading the file, then evaluated.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use matedit::brdf::{Isotropic, nbrdf};
use matedit_fuzz::clean_message;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Some(nets) = clean_message(Path::new("fuzz/nets.json"), nbrdf::parse(text)) {
        assert!(!nets.is_empty());
        for n in &nets {
            n.eval(0.3, 0.2, 1.0);
        }
    }
});
