//! MERL `.binary` tables: parsed, then looked up at angles in and out of range (the
//! lookups index the table with the file's own dimensions).
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use matedit::brdf::{Isotropic, merl};
use matedit_fuzz::clean_message;

fuzz_target!(|data: &[u8]| {
    if let Some(m) = clean_message(Path::new("fuzz/in.binary"), merl::parse(data, "fuzz")) {
        for a in [-1.0, 0.0, 0.3, 1.5707963, 2.0, 7.0, f64::INFINITY, f64::NAN] {
            let v = m.eval(a, a * 0.5, a * 3.0);
            assert!(v.iter().all(|x| *x >= 0.0));
            m.known(a, a, a);
        }
    }
});
