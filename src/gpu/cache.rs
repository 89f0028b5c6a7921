//! Compiled pipelines kept across processes: wgpu's pipeline cache (Vulkan adapters, which
//! have `PIPELINE_CACHE`), one file per adapter model in the user's cache folder, so that a
//! process's first call does not compile the shaders again.
//!
//! The folder: `MATEDIT_PIPELINE_CACHE` (a folder, or `off`), else
//! `$XDG_CACHE_HOME/matedit`, else `~/.cache/matedit`. A file that is unreadable, damaged
//! or made by another driver or wgpu is ignored (the shaders compile as without it) and
//! replaced; a folder that cannot be written only costs the next process the compile.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use super::context::GpuContext;

/// A pipeline cache and the file it was loaded from and is saved to.
pub struct DiskCache {
    cache: wgpu::PipelineCache,
    path: PathBuf,
    loaded: Option<Vec<u8>>,
}

/// The folder of the cache files; `None` when turned off or there is no home.
pub fn folder() -> Option<PathBuf> {
    let var = |name| std::env::var_os(name).filter(|v| !v.is_empty());
    if let Some(v) = var("MATEDIT_PIPELINE_CACHE") {
        return (v != "off").then(|| PathBuf::from(v));
    }
    var("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| var("HOME").map(|h| Path::new(&h).join(".cache")))
        .map(|c| c.join("matedit"))
}

/// FNV-1a, 64 bits: a file's contents are trusted only with their checksum.
fn checksum(data: &[u8]) -> [u8; 8] {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in data {
        h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
    }
    h.to_le_bytes()
}

/// The cache data in `file` (data, then its checksum), if whole.
fn checked(mut file: Vec<u8>) -> Option<Vec<u8>> {
    let n = file.len().checked_sub(8)?;
    let sum: [u8; 8] = file[n..].try_into().ok()?;
    file.truncate(n);
    (checksum(&file) == sum).then_some(file)
}

impl DiskCache {
    /// The cache of `ctx`'s adapter in `dir`, as far as the file there holds one; `None`
    /// where the device has no pipeline cache.
    pub fn open_in(ctx: &GpuContext, dir: &Path) -> Option<Self> {
        if !ctx.pipeline_cache {
            return None;
        }
        let path = dir.join(wgpu::util::pipeline_cache_key(&ctx.info)?);
        let loaded = std::fs::read(&path).ok().and_then(checked);
        // SAFETY: the data is what `get_data` gave a cache of this adapter model (the file
        // is named by its vendor and device, and checksummed); wgpu checks its header
        // (wgpu version, adapter, driver) and with `fallback` starts empty when it does
        // not match.
        let cache = unsafe {
            ctx.device
                .create_pipeline_cache(&wgpu::PipelineCacheDescriptor {
                    label: Some("matedit"),
                    data: loaded.as_deref(),
                    fallback: true,
                })
        };
        Some(DiskCache {
            cache,
            path,
            loaded,
        })
    }

    /// [`DiskCache::open_in`] the [`folder`].
    pub fn open(ctx: &GpuContext) -> Option<Self> {
        Self::open_in(ctx, &folder()?)
    }

    /// The cache, for the pipelines' descriptors.
    pub fn cache(&self) -> &wgpu::PipelineCache {
        &self.cache
    }

    /// The file it is saved to.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Whether it started from the file's data.
    pub fn was_loaded(&self) -> bool {
        self.loaded.is_some()
    }

    /// Writes the cache's data to its file where it changed (a new file, renamed into
    /// place, so that a reader never sees half of one); best effort.
    pub fn save(&self) {
        let Some(data) = self.cache.get_data() else {
            return;
        };
        if self.loaded.as_ref() == Some(&data) {
            return;
        }
        let Some(dir) = self.path.parent() else {
            return;
        };
        // a name of this process and save: renderers on several threads may save at once
        static SAVES: AtomicU64 = AtomicU64::new(0);
        let n = SAVES.fetch_add(1, Ordering::Relaxed);
        let tmp = (self.path).with_extension(format!("tmp-{}-{n}", std::process::id()));
        let write = || -> std::io::Result<()> {
            std::fs::create_dir_all(dir)?;
            let mut bytes = data.clone();
            bytes.extend_from_slice(&checksum(&data));
            std::fs::write(&tmp, bytes)?;
            std::fs::rename(&tmp, &self.path)
        };
        if write().is_err() {
            let _ = std::fs::remove_file(&tmp);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_damaged_file_is_not_trusted() {
        let data = b"pipeline bytes".to_vec();
        let mut file = data.clone();
        file.extend_from_slice(&checksum(&data));
        assert_eq!(checked(file.clone()), Some(data));
        file[3] ^= 1;
        assert_eq!(checked(file), None);
        assert_eq!(checked(vec![1, 2, 3]), None);
    }
}
