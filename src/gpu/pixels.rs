//! A scene's pixels as the GPU passes read them: which pixels are selected (the
//! foreground, or the foreground with a non-zero upstream gradient), their records
//! written straight into the upload buffer, and the per-pixel results scattered back into
//! an image, all in parallel over fixed chunks of candidates so that the records come in
//! the same order on any number of threads.

use rayon::prelude::*;

use super::layout::Pixel;
use crate::camera::Camera;
use crate::prepare::{PixelRec, is_foreground};
use crate::scene::{Image, NormalMap};

/// Candidates per chunk of the parallel passes.
const CHUNK: usize = 1 << 14;

/// Records per block written by one task.
const BLOCK: usize = 4096;

/// Bytes of a block of records.
const BLOCK_BYTES: usize = BLOCK * size_of::<Pixel>();

/// 16-byte words of a record.
const WORDS: usize = size_of::<Pixel>() / 16;

/// Where a scene's pixels come from: a prepared list, or a normal map read directly
/// (no list built: the records are computed where they are written).
#[derive(Clone, Copy)]
pub enum PixelSource<'a> {
    /// Listed pixels ([`crate::prepare::Prepared::pixels`]), in any order.
    Listed(&'a [PixelRec]),
    /// Every pixel of a normal map whose normal passes [`is_foreground`], in image order.
    Map(&'a NormalMap, Camera),
}

impl PixelSource<'_> {
    fn candidates(&self) -> usize {
        match self {
            PixelSource::Listed(p) => p.len(),
            PixelSource::Map(m, _) => m.normals.len(),
        }
    }

    /// Candidate `i`'s pixel index and record (upstream gradient zero), or `None` for a
    /// background pixel. The same values as [`Pixel::new`] of [`PixelRec::new`].
    fn pixel(&self, i: usize) -> Option<(usize, Pixel)> {
        match *self {
            PixelSource::Listed(p) => Some((p[i].index, Pixel::new(&p[i], [0.0; 3]))),
            PixelSource::Map(m, camera) => {
                let v = m.normals[i];
                let n = [v[0] as f64, v[1] as f64, v[2] as f64];
                if !is_foreground(n) {
                    return None;
                }
                let wp = camera.view_dir(i % m.width, i / m.width, m.width, m.height);
                Some((i, Pixel::new(&PixelRec::new(i, n, wp), [0.0; 3])))
            }
        }
    }

    /// Candidate `i`'s pixel index, or `None` for a background pixel ([`PixelSource::pixel`]
    /// without the record).
    fn index(&self, i: usize) -> Option<usize> {
        match *self {
            PixelSource::Listed(p) => Some(p[i].index),
            PixelSource::Map(m, _) => {
                let v = m.normals[i];
                is_foreground([v[0] as f64, v[1] as f64, v[2] as f64]).then_some(i)
            }
        }
    }

    /// Whether a source's pixel indices increase with the candidates, chunk by chunk, so
    /// that chunks scatter to disjoint parts of the image.
    fn ordered(&self) -> bool {
        matches!(self, PixelSource::Map(..))
    }
}

/// The pixels a pass reads: per chunk of candidates, where its records start.
pub struct Selection<'a> {
    source: PixelSource<'a>,
    upstream: Option<&'a Image>,
    active_only: bool,
    starts: Vec<usize>,
    len: usize,
}

impl<'a> Selection<'a> {
    /// The foreground pixels of `source`, with `upstream`'s gradient in their records;
    /// with `active_only`, only those whose gradient is non-zero.
    pub fn new(source: PixelSource<'a>, upstream: Option<&'a Image>, active_only: bool) -> Self {
        let mut sel = Selection {
            source,
            upstream,
            active_only,
            starts: Vec::new(),
            len: 0,
        };
        let counts: Vec<usize> = (0..source.candidates().div_ceil(CHUNK))
            .into_par_iter()
            .map(|c| sel.chunk(c).filter_map(|i| sel.index(i)).count())
            .collect();
        sel.starts = counts
            .iter()
            .scan(0, |acc, &n| {
                let s = *acc;
                *acc += n;
                Some(s)
            })
            .collect();
        sel.len = counts.iter().sum();
        sel
    }

    /// Records selected.
    pub fn len(&self) -> usize {
        self.len
    }

    /// What the records depend on: the source (its address and camera), the upstream
    /// image's address and the count. Two selections of one call with the same key have
    /// the same records: with the same source and upstream, one that leaves out pixels
    /// without a gradient and one that keeps them select the same pixels where their
    /// counts agree.
    pub fn key(&self) -> [usize; 4] {
        let (source, camera) = match self.source {
            PixelSource::Listed(p) => (p.as_ptr() as usize, usize::MAX),
            PixelSource::Map(m, Camera::Orthographic) => (m as *const NormalMap as usize, 0),
            PixelSource::Map(m, Camera::Perspective { fov_y_deg }) => {
                (m as *const NormalMap as usize, fov_y_deg.to_bits() as usize)
            }
        };
        let upstream = self.upstream.map_or(0, |u| u as *const Image as usize);
        [source, camera, upstream, self.len]
    }

    fn chunk(&self, c: usize) -> std::ops::Range<usize> {
        c * CHUNK..self.source.candidates().min((c + 1) * CHUNK)
    }

    /// Candidate `i`'s pixel index, where it is selected.
    fn index(&self, i: usize) -> Option<usize> {
        let index = self.source.index(i)?;
        match self.upstream {
            Some(u) if self.active_only && !u.pixels[index].iter().any(|&v| v != 0.0) => None,
            _ => Some(index),
        }
    }

    /// Candidate `i`'s pixel index and record, where it is selected.
    fn record(&self, i: usize) -> Option<(usize, Pixel)> {
        self.index(i)?;
        let (index, mut p) = self.source.pixel(i)?;
        if let Some(u) = self.upstream {
            let g = u.pixels[index];
            p.g = [g[0], g[1], g[2], 0.0];
        }
        Some((index, p))
    }

    /// Writes the records, in order, at the start of `out` (mapped memory), a block of
    /// [`BLOCK`] records per task on all cores.
    pub fn write(&self, out: wgpu::WriteOnly<'_, [u8]>) {
        let out = out.into_slice(..self.len * size_of::<Pixel>());
        let (blocks, rest) = out.into_chunks::<BLOCK_BYTES>();
        let n_blocks = blocks.len();
        let blocks: Vec<wgpu::WriteOnly<'_, [u8; BLOCK_BYTES]>> = blocks.into_iter().collect();
        blocks.into_par_iter().enumerate().for_each(|(j, block)| {
            self.write_block(j * BLOCK, block.into());
        });
        self.write_block(n_blocks * BLOCK, rest);
    }

    /// Writes records `first..` into `out` (whole records).
    fn write_block(&self, first: usize, out: wgpu::WriteOnly<'_, [u8]>) {
        let n = out.len() / size_of::<Pixel>();
        if n == 0 {
            return;
        }
        // the chunk of candidates that holds record `first`, and the records before it there
        let c = self.starts.partition_point(|&s| s <= first) - 1;
        let skip = first - self.starts[c];
        // skipped by their index alone: only the records written are computed
        let recs = (c * CHUNK..self.source.candidates())
            .filter(|&i| self.index(i).is_some())
            .skip(skip)
            .take(n)
            .filter_map(|i| self.record(i))
            .flat_map(|(_, p)| bytemuck::cast::<Pixel, [[u8; 16]; WORDS]>(p));
        out.into_chunks::<16>().0.write_iter(recs);
    }

    /// An image of `width` x `height` with each selected pixel's vec4 result from `vals`
    /// (four values a record, in record order) and zeros elsewhere.
    pub fn scatter(&self, vals: &[f32], width: usize, height: usize) -> Vec<[f32; 3]> {
        let mut img = vec![[0.0f32; 3]; width * height];
        if !self.source.ordered() {
            let indices = (0..self.source.candidates()).filter_map(|i| self.index(i));
            for (index, v) in indices.zip(vals.chunks_exact(4)) {
                img[index] = [v[0], v[1], v[2]];
            }
            return img;
        }
        // a map's chunk c holds pixels c * CHUNK.. in order: its own part of the image
        let vals = &vals[..self.len * 4];
        img.par_chunks_mut(CHUNK)
            .zip(self.split_ref(vals))
            .enumerate()
            .for_each(|(c, (part, vals))| {
                let base = c * CHUNK;
                let indices = self.chunk(c).filter_map(|i| self.index(i));
                for (index, v) in indices.zip(vals.chunks_exact(4)) {
                    part[index - base] = [v[0], v[1], v[2]];
                }
            });
        img
    }

    /// The chunks' parts of `vals` (four values a record).
    fn split_ref<'v>(&self, vals: &'v [f32]) -> Vec<&'v [f32]> {
        (0..self.starts.len())
            .map(|c| {
                let end = self.starts.get(c + 1).copied().unwrap_or(self.len);
                &vals[self.starts[c] * 4..end * 4]
            })
            .collect()
    }
}
