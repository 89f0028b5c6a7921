//! Nothing panics on arbitrary or corrupted files; errors are one line naming the file.

use proptest::prelude::*;
use proptest::sample::select;

use crate::binary_files::{
    exr_file, exr_mutant, merl_file, merl_mutant, npy_file, npy_mutant, png_file, png_mutant,
};
use crate::json_files::{edit_json, json_edit, manifest_json, material_json, nbrdf_json};
use crate::mutations::{mutate, mutation};
use crate::{load_all, load_file};

/// The first bytes of each format.
const MAGICS: &[&[u8]] = &[
    b"\x93NUMPY\x01\x00",
    b"\x93NUMPY\x02\x00",
    b"\x76\x2f\x31\x01\x02\x00\x00\x00",
    b"\x89PNG\r\n\x1a\n",
    b"{\"ctrl\": ",
    b"{\"format\": \"nbrdf-6-21-21-3\", \"materials\": ",
];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..512)) {
        for ext in [".npy", ".exr", ".png", ".json", ".binary"] {
            load_all(ext, &bytes)?;
        }
    }

    /// Arbitrary bytes behind each format's magic number, so that they reach the parsers.
    #[test]
    fn bytes_after_a_magic_number_never_panic(
        magic in select(MAGICS),
        tail in prop::collection::vec(any::<u8>(), 0..512),
    ) {
        let bytes = [magic, &tail[..]].concat();
        for ext in [".npy", ".exr", ".png", ".json"] {
            load_all(ext, &bytes)?;
        }
    }

    #[test]
    fn corrupted_npy_files_are_clean(b in npy_file(), m in mutation()) {
        load_all(".npy", &mutate(b, &m))?;
    }

    #[test]
    fn npy_header_fields_are_checked(b in npy_mutant(), m in mutation()) {
        load_all(".npy", &mutate(b, &m))?;
    }

    #[test]
    fn corrupted_png_files_are_clean(b in png_file(), m in mutation()) {
        load_all(".png", &mutate(b, &m))?;
    }

    #[test]
    fn png_header_fields_are_checked(b in png_mutant(), m in mutation()) {
        load_all(".png", &mutate(b, &m))?;
    }

    #[test]
    fn corrupted_json_files_are_clean(
        doc in prop_oneof![material_json(), manifest_json(), nbrdf_json()],
        e in prop::option::of(json_edit()),
        m in mutation(),
    ) {
        let bytes = match &e {
            Some(e) => edit_json(doc, e),
            None => serde_json::to_vec(&doc).expect("json"),
        };
        load_all(".json", &mutate(bytes, &m))?;
    }

    #[test]
    fn corrupted_merl_tables_are_clean(b in prop_oneof![merl_file(), merl_mutant()], m in mutation()) {
        load_all(".binary", &mutate(b, &m))?;
    }
}

proptest! {
    // EXR decoding is the slowest loader: fewer cases
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn corrupted_exr_files_are_clean(b in exr_file(), m in mutation()) {
        load_all(".exr", &mutate(b, &m))?;
    }

    #[test]
    fn exr_header_fields_are_checked(b in exr_mutant(), m in mutation()) {
        load_all(".exr", &mutate(b, &m))?;
    }
}

proptest! {
    // a temporary folder and 11 loaders per case
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Through the files the command line opens: every path-based loader on every kind of
    /// corrupted file, under each extension.
    #[test]
    fn path_loaders_are_clean(
        b in prop_oneof![
            npy_file(), exr_file(), png_file(), merl_file(),
            material_json().prop_map(|v| serde_json::to_vec(&v).expect("json")),
            prop::collection::vec(any::<u8>(), 0..64),
        ],
        m in mutation(),
        ext in select(&["npy", "exr", "png", "json", "binary"][..]),
    ) {
        load_file(&format!("in.{ext}"), &mutate(b, &m))?;
    }
}
