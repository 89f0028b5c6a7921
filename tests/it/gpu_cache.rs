//! Compiled pipelines kept across processes (wgpu's pipeline cache, on Vulkan adapters):
//! saved to a file, loaded from it, and a damaged file ignored.

use crate::common;

use matedit::gpu::cache::DiskCache;
use matedit::gpu::pipelines::Pipeline;
use matedit::gpu::{Pass, Tiles};

#[test]
fn pipelines_are_saved_loaded_and_a_damaged_file_ignored() {
    let test = "pipelines_are_saved_loaded_and_a_damaged_file_ignored";
    let Some(g) = common::gpu(test) else {
        return;
    };
    let ctx = g.context();
    let dir = tempfile::tempdir().unwrap();
    let Some(first) = DiskCache::open_in(ctx, dir.path()) else {
        assert!(
            !ctx.pipeline_cache,
            "a device with PIPELINE_CACHE has a cache"
        );
        eprintln!("SKIPPED {test}: {} has no pipeline cache", ctx.describe());
        return;
    };
    assert!(!first.was_loaded(), "an empty folder holds nothing to load");
    for tiles in [Tiles::Workgroup, Tiles::Uniform] {
        for pass in Pass::ALL {
            Pipeline::new(&ctx.device, pass, tiles, Some(first.cache()));
        }
    }
    first.save();
    let bytes = std::fs::read(first.path()).expect("the cache was saved");
    assert!(bytes.len() > 8, "{} bytes", bytes.len());
    let again = DiskCache::open_in(ctx, dir.path()).unwrap();
    assert!(again.was_loaded(), "the saved file is loaded");
    let mut damaged = bytes.clone();
    damaged[bytes.len() / 2] ^= 0x40;
    std::fs::write(first.path(), &damaged).unwrap();
    let third = DiskCache::open_in(ctx, dir.path()).unwrap();
    assert!(!third.was_loaded(), "a damaged file is not loaded");
    // and the pipelines still build through the empty cache
    Pipeline::new(
        &ctx.device,
        Pass::Forward,
        Tiles::Uniform,
        Some(third.cache()),
    );
}
