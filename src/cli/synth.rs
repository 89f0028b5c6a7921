//! `matedit synth`: a dataset of samples drawn from a spec, rendered and written as tar
//! chunks (one shard of them, or all), or the chunks checked.

use std::path::PathBuf;

use matedit::synth::{self, Shard};
use matedit::{Device, Error};

use super::shared::{Failure, progress_bar, runtime, threads};

/// Shown after the options by `matedit help synth`.
pub const EXAMPLES: &str = "\
Examples:
  matedit synth spec.json -o dataset/
  matedit synth spec.json -o dataset/ --shard 3/16      (one task of an array job)
  matedit synth spec.json -o dataset/ --verify          (after the shards: check, list all)

spec.json: {\"count\": 12, \"seed\": 7, \"image_size\": 64, \"env_size\": \"32x64\",
  \"normals\": [{\"sphere\": 64}, {\"bumpy\": 64}], \"envs\": [\"sky.exr\"],
  \"materials\": [{\"preset\": \"gold\"}, {\"random\": \"merl\"}]}
Writes DIR/chunk-NNNNNN.tar (WebDataset style: KEY.env.npy, KEY.image.npy,
KEY.material.json, KEY.normals.npy, KEY.params.json per sample), a record
chunk-NNNNNN.json beside each, and DIR/manifest.json. Sample k depends on the spec,
its seed and k alone: any split into shards writes the same chunk files, bit for bit.
A re-run skips the chunks already complete. See docs/synth.md.";

/// The options of `matedit synth`.
#[derive(clap::Args)]
pub struct Args {
    /// The spec: a JSON file naming the sources, the count, the sizes and the seed (see docs/synth.md).
    spec: PathBuf,
    /// Output folder (created if missing).
    #[arg(short, long, value_name = "DIR")]
    output: PathBuf,
    /// Write only shard I of N: the chunks c with c mod N = I (for array jobs).
    #[arg(long, value_name = "I/N", default_value = "0/1")]
    shard: Shard,
    /// Backend: cpu (the fast f32 SIMD path), gpu, reference or auto. The chunks' bits depend on it (and on the CPU path's instruction set, see MATEDIT_SIMD), not on the split or the thread count.
    #[arg(long, value_name = "cpu|gpu|reference|auto", default_value = "cpu")]
    device: Device,
    /// Worker threads of the CPU paths [default: RAYON_NUM_THREADS, else one per core].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    /// Render nothing: check every chunk against its record and rewrite the manifest; fails if any chunk is missing.
    #[arg(long, conflicts_with = "shard")]
    verify: bool,
}

/// Runs `matedit synth`.
pub fn run(args: &Args) -> Result<(), Failure> {
    let spec = synth::Spec::load(&args.spec)?;
    threads(args.threads);
    let engine = synth::Engine::new(args.device)?;
    if args.verify {
        let v = synth::verify(&spec, &args.output, &engine.label)?;
        eprintln!(
            "matedit: synth: {} of {} chunks present and verified; wrote {}",
            v.chunks_present,
            v.chunks_total,
            args.output.join("manifest.json").display()
        );
        if !v.missing.is_empty() {
            let names: Vec<String> = v
                .missing
                .iter()
                .take(8)
                .map(|&c| synth::chunk_file(&spec, c))
                .collect();
            return Err(runtime(Error::file(
                &args.output,
                format!(
                    "{} chunk{} missing or not matching {} record: {}{}; run the shards again",
                    v.missing.len(),
                    if v.missing.len() == 1 { "" } else { "s" },
                    if v.missing.len() == 1 { "its" } else { "their" },
                    names.join(", "),
                    if v.missing.len() > 8 { ", ..." } else { "" }
                ),
            )));
        }
        return Ok(());
    }
    let shard = args.shard;
    synth::check_output(&spec, &args.output, &engine.label)?;
    eprintln!("matedit: device: {}", engine.renderer.describe());
    let mine = shard.chunks(spec.chunks()).count() as u64 * spec.chunk_size;
    if mine == 0 {
        // an array job with more tasks than chunks: this task succeeds with nothing to do
        let total = spec.chunks();
        eprintln!(
            "matedit: synth: shard {shard}: no chunk to write (the spec makes {total} chunk{}, \
             shards {total}/{n} on have none); nothing written",
            if total == 1 { "" } else { "s" },
            n = shard.count,
        );
        return Ok(());
    }
    let bar = progress_bar(
        mine,
        "{prefix} {bar:30} {pos}/{len} samples {elapsed} (eta {eta})",
    );
    if let Some(b) = &bar {
        b.set_prefix(format!("shard {shard}"));
    }
    let progress = |n: u64| {
        if let Some(b) = &bar {
            b.inc(n);
        }
    };
    let s = synth::run(&spec, &args.output, shard, &engine, &progress).map_err(runtime)?;
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    eprintln!(
        "matedit: synth: shard {}: {} samples in {:.2} s ({:.1} samples/s), {} chunk{} written, {} skipped; {} of {} chunks present in {}",
        s.shard,
        s.samples,
        s.seconds,
        s.samples_per_second(),
        s.chunks_written,
        if s.chunks_written == 1 { "" } else { "s" },
        s.chunks_skipped,
        s.chunks_present,
        s.chunks_total,
        args.output.display()
    );
    Ok(())
}
