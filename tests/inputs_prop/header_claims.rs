//! Header claims: no loader allocates for them before checking them against the file
//! (a counting global allocator watches the largest request).

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

use exr::prelude::{self as ex};
use matedit::brdf::merl;
use matedit::io::{self, npy};

use crate::binary_files::{exr_bytes, npy_bytes, npy_header};
use crate::mutations::{exr_attr, patch_ihdr, put};

/// The global allocator, counting the largest request since [`largest_since`] last reset.
struct Counting;

static LARGEST: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every call is passed to the system allocator unchanged.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LARGEST.fetch_max(new_size, Ordering::Relaxed);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Runs `f` and returns its result with the largest allocation made meanwhile (by any
/// thread: the other tests here allocate kilobytes, far below what is checked).
fn largest_since<T>(f: impl FnOnce() -> T) -> (T, usize) {
    LARGEST.store(0, Ordering::Relaxed);
    let out = f();
    (out, LARGEST.load(Ordering::Relaxed))
}

/// Writes `bytes` as `name` in a temporary folder and loads it with `load`: the error must
/// say `says`, name the file, come within a second and allocate no more than 16 MiB at once.
fn refused_cheaply<T: std::fmt::Debug>(
    name: &str,
    bytes: &[u8],
    load: fn(&Path) -> matedit::Result<T>,
    says: &str,
) {
    let dir = tempfile::tempdir().expect("temp dir");
    let p = dir.path().join(name);
    std::fs::write(&p, bytes).expect("write");
    let start = std::time::Instant::now();
    let (r, largest) = largest_since(|| load(&p));
    let took = start.elapsed();
    let e = r
        .expect_err("a file claiming more than it holds")
        .to_string();
    assert!(
        e.starts_with(&p.display().to_string()) && !e.contains('\n'),
        "{e}"
    );
    assert!(e.contains(says), "{name}: {e}");
    assert!(
        largest <= 16 << 20,
        "{name}: allocated {largest} bytes at once: {e}"
    );
    assert!(took.as_secs_f64() < 1.0, "{name}: took {took:?}");
}

#[test]
fn headers_claiming_huge_sizes_are_refused_before_allocating() {
    // EXR: a 2 x 2 file whose data window says 16000 x 16000 (within MAX_PIXELS), its
    // chunk count to match (the decoder allocated 1 GB a channel before reading a chunk)
    for (comp, lines) in [
        (ex::Compression::Uncompressed, 1),
        (ex::Compression::ZIP16, 16),
        (ex::Compression::DWAA(None), 32),
    ] {
        let mut b = exr_bytes(2, 2, &[[0.5; 3]; 4], comp, false, false);
        let window: Vec<u8> = [0i32, 0, 15999, 15999]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        for name in ["dataWindow", "displayWindow"] {
            let at = exr_attr(&b, name, "box2i").expect("window");
            put(&mut b, at, &window);
        }
        let at = exr_attr(&b, "chunkCount", "int").expect("chunk count");
        put(&mut b, at, &(16000i32 / lines).to_le_bytes());
        refused_cheaply(
            "big.exr",
            &b,
            |p| io::read_raster(p, "a raster"),
            "more than a",
        );
    }

    // PNG: a 1 x 1 RGB file whose header says 16000 x 16000 (768 MB, within png's limit)
    let mut b = io::png::encode_rgb8(1, 1, &[1, 2, 3]).expect("png");
    patch_ihdr(&mut b, 16000, 16000, 8, 2, 0);
    refused_cheaply("big.png", &b, io::load_normals, "more than a");
    refused_cheaply("big.png", &b, io::load_image, "more than a");

    // NPY: shape (100000, 100000, 3) and no data
    let header = npy_header("<f4", "False", "(100000, 100000, 3)");
    let b = npy_bytes(1, &header, &[0; 16]);
    refused_cheaply("big.npy", &b, io::load_normals, "truncated");
    // and a shape of more axes than NumPy writes
    let header = npy_header("<f4", "True", &format!("({}2,)", "1, ".repeat(100)));
    let b = npy_bytes(1, &header, &[0; 8]);
    refused_cheaply("axes.npy", &b, npy::read, "axes");

    // MERL: 1024 x 1024 x 1024 cells claimed, none there
    let b: Vec<u8> = [1024i32; 3].iter().flat_map(|d| d.to_le_bytes()).collect();
    refused_cheaply(
        "big.binary",
        &b,
        merl::read,
        "header says 1024 x 1024 x 1024",
    );
}
