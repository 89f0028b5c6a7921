//! Dataset synthesis: many rendered samples drawn from a spec ([`Spec`]), written as
//! WebDataset-style tar chunks that any split of the work writes bit for bit alike.
//!
//! Sample `k` is a pure function of (spec, seed, k) ([`Spec::sample`]); samples are grouped
//! by index into chunks of `chunk_size`; shard `I/N` ([`Shard`]) writes the chunks
//! `c` with `c mod N == I`. Each chunk is written to a temporary file in the output folder
//! and renamed into place, then its record (`chunk-NNNNNN.json`: first sample, count,
//! size, SHA-256, the spec's digest and the renderer) likewise; a run skips a chunk whose
//! tar matches its record, so a killed run resumes where it stopped. `manifest.json` lists
//! the chunks present; each run rewrites it atomically at its end (shards running at once
//! each list what they see: the last to finish, or [`verify`], lists all).
//!
//! docs/synth.md describes the spec, the files and how to run shards on Slurm, Kubernetes
//! and Ray.
//!
//! Files: [`spec`] (the spec and its top-level keys) on [`sources`] (its source lists) on
//! `files.rs` (the files and folders it names); [`draw`] (sample k) on `draws.rs` (an
//! item by weight, a material); [`world`] (the photo-like options: fov and elevation
//! ranges) with [`floor`], [`textures`], [`shadow`] and [`clutter`] (other objects on the
//! floor); [`camera_effects`] and [`edit`] (what a sample's render becomes: a photo as
//! a camera writes it, the true edit beside it); [`tar`] (a chunk's
//! bytes); `chunk.rs` (a chunk's file, its record, the check that skips it); [`shard`];
//! this file (the engine, running a shard, verifying, the manifest).

pub mod augment;
pub mod background;
pub mod camera_effects;
mod chunk;
pub mod clutter;
pub mod draw;
mod draws;
pub mod edit;
mod files;
pub mod floor;
pub mod perturb;
pub mod shadow;
pub mod shard;
pub mod sources;
pub mod spec;
pub mod tar;
pub mod textures;
pub mod world;

use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use crate::error::{Error, Result};
use crate::renderer::Picked;
use crate::scene::Batch;
use crate::{Device, Renderer};

pub use chunk::{ChunkRecord, chunk_file};
use chunk::{check_chunk, record_file, remove_leftovers, sha256_hex, write_atomic};
pub use draw::Sample;
pub use shard::Shard;
pub use spec::Spec;

/// The `format` of `manifest.json` and of the chunk records.
pub const FORMAT: &str = "matedit-synth 2";

/// A renderer and the name of what it computes: samples record it, and a chunk made by
/// another renderer is not taken as done.
pub struct Engine {
    /// The renderer.
    pub renderer: Renderer,
    /// `cpu-avx512`, `cpu-avx2`, `cpu-neon`, `cpu-scalar`, `reference`, or the GPU's
    /// description. The fast CPU path's bits depend on its instruction set, not on the
    /// thread count.
    pub label: String,
    parallel: bool,
}

impl Engine {
    /// The renderer for `device` (`Auto`: a hardware GPU, else the fast CPU path).
    pub fn new(device: Device) -> Result<Engine> {
        Ok(match device.pick()? {
            Picked::Cpu(fast) => Engine {
                label: format!("cpu-{}", fast.level().name()),
                renderer: Renderer::with_backend(Box::new(fast)),
                parallel: true,
            },
            Picked::Reference(r) => Engine {
                label: "reference".into(),
                renderer: Renderer::with_backend(Box::new(r)),
                parallel: true,
            },
            Picked::Gpu(gpu) => {
                let renderer = Renderer::with_backend(gpu);
                Engine {
                    label: renderer.describe(),
                    renderer,
                    parallel: false,
                }
            }
        })
    }
}

/// What a run did.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Summary {
    /// The shard that ran, as `I/N`.
    pub shard: String,
    /// Samples rendered and written.
    pub samples: u64,
    /// Chunks written.
    pub chunks_written: u64,
    /// Chunks found complete and skipped.
    pub chunks_skipped: u64,
    /// Seconds the run took (loading the spec excluded).
    pub seconds: f64,
    /// Chunks of the whole dataset.
    pub chunks_total: u64,
    /// Chunks the manifest written at the end lists.
    pub chunks_present: u64,
    /// The renderer's label.
    pub renderer: String,
}

impl Summary {
    /// Rendered samples per second.
    pub fn samples_per_second(&self) -> f64 {
        if self.seconds > 0.0 {
            self.samples as f64 / self.seconds
        } else {
            0.0
        }
    }
}

/// Checks that `dir` can take this dataset: not a file, and no manifest of another spec
/// or renderer in it.
pub fn check_output(spec: &Spec, dir: &Path, renderer: &str) -> Result<()> {
    if dir.exists() && !dir.is_dir() {
        return Err(Error::file(dir, "is a file; give a folder for the dataset"));
    }
    let manifest = dir.join("manifest.json");
    if let Ok(bytes) = std::fs::read(&manifest) {
        let v: serde_json::Value = serde_json::from_slice(&bytes)
            .map_err(|e| Error::file(&manifest, format!("not a dataset manifest: {e}")))?;
        let digest = v["spec_sha256"].as_str().unwrap_or("");
        if digest != spec.digest {
            return Err(Error::file(
                &manifest,
                format!(
                    "the folder holds a dataset of another spec (or other input files): \
                     spec_sha256 {digest}, this spec's is {}; write to another folder or \
                     remove it",
                    spec.digest
                ),
            ));
        }
        let theirs = v["renderer"].as_str().unwrap_or("");
        if theirs != renderer {
            return Err(Error::file(
                &manifest,
                format!(
                    "the folder's chunks were rendered by '{theirs}', this run renders with \
                     '{renderer}' (other bits); use that device (MATEDIT_SIMD pins the CPU \
                     path's instruction set) or another folder"
                ),
            ));
        }
    }
    Ok(())
}

/// Renders chunk `c` of the dataset: its tar bytes.
pub fn render_chunk(
    spec: &Spec,
    engine: &Engine,
    c: u64,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Vec<u8>> {
    let first = c * spec.chunk_size;
    let width = tar::key_width(spec.count);
    let one = |k: u64| -> Result<tar::Keyed> {
        let mut sample = spec.sample(k)?;
        let batch = Batch::single(sample.scene.clone())
            .map_err(|e| Error::Invalid(format!("sample {k}: {e}")))?;
        let image = engine
            .renderer
            .render(&batch)
            .map_err(|e| Error::Invalid(format!("sample {k}: {e}")))?
            .remove(0);
        let members = edit::finish(&mut sample, image, engine)?;
        progress(1);
        Ok((format!("{k:0width$}"), members))
    };
    let range = first..first + spec.chunk_size;
    let samples: Vec<_> = if engine.parallel {
        range.into_par_iter().map(one).collect::<Result<_>>()?
    } else {
        range.map(one).collect::<Result<_>>()?
    };
    tar::encode(&samples)
}

/// Runs one shard into `dir` (created if missing): writes its chunks that are not yet
/// complete, then the manifest. A shard may have no chunk to write (more shards than
/// chunks, as an array job sized for a larger spec): it then writes only the manifest of
/// the chunks present ([`Summary::chunks_written`] is 0). `progress` is told of each sample rendered or skipped.
pub fn run(
    spec: &Spec,
    dir: &Path,
    shard: Shard,
    engine: &Engine,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Summary> {
    check_output(spec, dir, &engine.label)?;
    let start = Instant::now();
    let created = crate::io::create_dirs(dir)?;
    let result = run_chunks(spec, dir, shard, engine, progress, start);
    if result.is_err() {
        // folders this run made and left empty go too
        crate::io::remove_created(&created);
    }
    result
}

fn run_chunks(
    spec: &Spec,
    dir: &Path,
    shard: Shard,
    engine: &Engine,
    progress: &(dyn Fn(u64) + Sync),
    start: Instant,
) -> Result<Summary> {
    let total = spec.chunks();
    let mut summary = Summary {
        shard: shard.to_string(),
        chunks_total: total,
        renderer: engine.label.clone(),
        ..Default::default()
    };
    for c in shard.chunks(total) {
        if check_chunk(spec, dir, c, &engine.label, true).is_some() {
            summary.chunks_skipped += 1;
            progress(spec.chunk_size);
            continue;
        }
        let name = chunk_file(spec, c);
        remove_leftovers(dir, &name);
        remove_leftovers(dir, &record_file(&name));
        let bytes = render_chunk(spec, engine, c, progress)?;
        let record = ChunkRecord {
            format: FORMAT.into(),
            file: name.clone(),
            chunk: c,
            first: c * spec.chunk_size,
            count: spec.chunk_size,
            bytes: bytes.len() as u64,
            sha256: sha256_hex(&bytes),
            spec_sha256: spec.digest.clone(),
            renderer: engine.label.clone(),
        };
        let mut rec_bytes = serde_json::to_vec_pretty(&record).unwrap_or_default();
        rec_bytes.push(b'\n');
        // a record left over from another spec would otherwise vouch for the new tar
        let _ = std::fs::remove_file(dir.join(record_file(&name)));
        write_atomic(dir, &name, &bytes)?;
        write_atomic(dir, &record_file(&name), &rec_bytes)?;
        summary.chunks_written += 1;
        summary.samples += spec.chunk_size;
    }
    summary.seconds = start.elapsed().as_secs_f64();
    let present = write_manifest(spec, dir, &engine.label, false)?;
    summary.chunks_present = present.len() as u64;
    Ok(summary)
}

/// What [`verify`] found.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Verified {
    /// Chunks of the whole dataset.
    pub chunks_total: u64,
    /// Chunks whose tar matches its record.
    pub chunks_present: u64,
    /// Chunks missing or not matching their record.
    pub missing: Vec<u64>,
}

/// Checks every chunk of the dataset in `dir` against its record (re-reading each tar)
/// and rewrites the manifest listing those that match: the final step after shards ran
/// at the same time.
pub fn verify(spec: &Spec, dir: &Path, renderer: &str) -> Result<Verified> {
    if !dir.is_dir() {
        return Err(Error::file(dir, "no such folder"));
    }
    check_output(spec, dir, renderer)?;
    let present = write_manifest(spec, dir, renderer, true)?;
    let total = spec.chunks();
    let missing = (0..total)
        .filter(|c| !present.iter().any(|r| r.chunk == *c))
        .collect();
    Ok(Verified {
        chunks_total: total,
        chunks_present: present.len() as u64,
        missing,
    })
}

/// Writes `dir/manifest.json` listing the chunks present (with `hash`, re-hashed); returns
/// their records.
fn write_manifest(spec: &Spec, dir: &Path, renderer: &str, hash: bool) -> Result<Vec<ChunkRecord>> {
    let total = spec.chunks();
    let present: Vec<ChunkRecord> = (0..total)
        .into_par_iter()
        .filter_map(|c| check_chunk(spec, dir, c, renderer, hash))
        .collect();
    let samples: u64 = present.iter().map(|r| r.count).sum();
    let spec_name = spec
        .path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let manifest = serde_json::json!({
        "format": FORMAT,
        "spec": spec_name,
        "spec_sha256": spec.digest,
        "renderer": renderer,
        "count": spec.count,
        "seed": spec.seed,
        "chunk_size": spec.chunk_size,
        "chunks_total": total,
        "chunks_present": present.len(),
        "samples_present": samples,
        "complete": present.len() as u64 == total,
        "image_size": [spec.image_size.1, spec.image_size.0],
        "env_size": [spec.env_size.0, spec.env_size.1],
        "members": spec.members(),
        "chunks": present.iter().map(|r| serde_json::json!({
            "file": r.file, "first": r.first, "count": r.count,
            "bytes": r.bytes, "sha256": r.sha256,
        })).collect::<Vec<_>>(),
    });
    let mut bytes = serde_json::to_vec_pretty(&manifest).unwrap_or_default();
    bytes.push(b'\n');
    write_atomic(dir, "manifest.json", &bytes)?;
    Ok(present)
}

/// The data files of a dataset folder (chunk tars and their records), sorted: what any
/// split of a run writes alike.
pub fn data_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::file(dir, format!("cannot list: {e}")))?
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("chunk-"))
        })
        .collect();
    out.sort();
    Ok(out)
}
