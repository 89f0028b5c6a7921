//! One chunk on disk: its tar file's name, its record (`chunk-NNNNNN.json`) and the
//! check that a chunk already written belongs to this spec and renderer and is whole, so
//! that a re-run skips it; atomic writes and what a killed run left behind.

use std::path::Path;

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::FORMAT;
use super::spec::{self, Spec};
use crate::error::Result;

/// What a chunk's record (`chunk-NNNNNN.json`) says.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChunkRecord {
    /// [`FORMAT`].
    pub format: String,
    /// The tar file's name.
    pub file: String,
    /// The chunk's index.
    pub chunk: u64,
    /// Its first sample.
    pub first: u64,
    /// Its samples.
    pub count: u64,
    /// The tar file's size.
    pub bytes: u64,
    /// The tar file's SHA-256, hex.
    pub sha256: String,
    /// The spec's digest ([`Spec::digest`]).
    pub spec_sha256: String,
    /// The renderer's label ([`super::Engine::label`]).
    pub renderer: String,
}

/// The tar file of chunk `c`.
pub fn chunk_file(spec: &Spec, c: u64) -> String {
    let width = spec.chunks().saturating_sub(1).to_string().len().max(6);
    format!("chunk-{c:0width$}.tar")
}

pub(super) fn record_file(tar_name: &str) -> String {
    format!("{}.json", tar_name.trim_end_matches(".tar"))
}

pub(super) fn sha256_hex(bytes: &[u8]) -> String {
    spec::hex(&Sha256::digest(bytes))
}

/// The record of chunk `c` in `dir` if it belongs to this spec and renderer, and with
/// `hash` its tar's size and checksum match it.
pub(super) fn check_chunk(
    spec: &Spec,
    dir: &Path,
    c: u64,
    renderer: &str,
    hash: bool,
) -> Option<ChunkRecord> {
    let name = chunk_file(spec, c);
    let rec_bytes = std::fs::read(dir.join(record_file(&name))).ok()?;
    let rec: ChunkRecord = serde_json::from_slice(&rec_bytes).ok()?;
    let expected = (
        FORMAT,
        name.as_str(),
        c,
        c * spec.chunk_size,
        spec.chunk_size,
        spec.digest.as_str(),
        renderer,
    );
    let got = (
        rec.format.as_str(),
        rec.file.as_str(),
        rec.chunk,
        rec.first,
        rec.count,
        rec.spec_sha256.as_str(),
        rec.renderer.as_str(),
    );
    if expected != got {
        return None;
    }
    let path = dir.join(&name);
    if hash {
        let bytes = std::fs::read(&path).ok()?;
        (bytes.len() as u64 == rec.bytes && sha256_hex(&bytes) == rec.sha256).then_some(rec)
    } else {
        let meta = std::fs::metadata(&path).ok()?;
        (meta.is_file() && meta.len() == rec.bytes).then_some(rec)
    }
}

/// Writes `bytes` to `dir/name` atomically, through a temporary file `.name.XXXX.tmp`
/// ([`crate::io::stage`]) and a rename.
pub(super) fn write_atomic(dir: &Path, name: &str, bytes: &[u8]) -> Result<()> {
    crate::io::write_atomic(&dir.join(name), bytes)
}

/// Removes what a killed run left of chunk file `name`: its temporary files.
pub(super) fn remove_leftovers(dir: &Path, name: &str) {
    let prefix = format!(".{name}.");
    if let Ok(entries) = std::fs::read_dir(dir) {
        for e in entries.flatten() {
            let n = e.file_name();
            let n = n.to_string_lossy();
            if n.starts_with(&prefix) && n.ends_with(".tmp") {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
}
