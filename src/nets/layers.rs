//! The layers of model.py in candle, named as its modules are (`block`, `Encoder`,
//! `NormalsNet`, `GlobalNet`), each built from its tensors in a [`Weights`].

use candle_core::{D, Result, Tensor};
use rayon::prelude::*;

use super::weights::{NetsConfig, Weights};
use crate::error::Result as MResult;

/// GroupNorm's epsilon (PyTorch's default).
const GN_EPS: f64 = 1e-5;

/// `nn.Conv2d` (stride 1, padding k / 2) with bias, on one image, as a matrix product of
/// the flattened kernel (cout, cin k k) and the image's k x k neighbourhoods (cin k k, H W).
/// Not candle's `conv2d`: candle-core 0.9.2's CPU convolution gives wrong sums for some
/// shapes (a 16 x 16 image, 16 -> 8 channels: 4.85 off a direct loop; 12 x 20 is right).
struct Conv {
    /// (cout, cin k k)
    weight: Tensor,
    bias: Tensor,
    k: usize,
}

impl Conv {
    fn new(w: &mut Weights, name: &str, cin: usize, cout: usize, k: usize) -> MResult<Self> {
        Ok(Conv {
            weight: w
                .take(&format!("{name}.weight"), &[cout, cin, k, k])?
                .reshape((cout, cin * k * k))?,
            bias: w
                .take(&format!("{name}.bias"), &[cout])?
                .reshape((1, cout, 1, 1))?,
            k,
        })
    }

    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let (b, cin, h, w) = x.dims4()?;
        let (k, p) = (self.k, self.k / 2);
        let cols = if k == 1 {
            x.reshape((b * cin, h * w))?
        } else {
            let cols = im2col(&x.flatten_all()?.to_vec1::<f32>()?, b * cin, h, w, k, p);
            Tensor::from_vec(cols, (b * cin * k * k, h * w), x.device())?
        };
        let cout = self.weight.dim(0)?;
        self.weight
            .matmul(&cols)?
            .reshape((b, cout, h, w))?
            .broadcast_add(&self.bias)
    }
}

/// The k x k neighbourhoods of `c` channels of H x W (zero outside, `p` pixels of padding)
/// as rows (c k k, H W): row (ci k + ky) k + kx is channel ci shifted by (ky - p, kx - p),
/// the flat order of a convolution's kernel.
fn im2col(x: &[f32], c: usize, h: usize, w: usize, k: usize, p: usize) -> Vec<f32> {
    let mut cols = vec![0f32; c * k * k * h * w];
    cols.par_chunks_mut(k * k * h * w)
        .zip(x.par_chunks(h * w))
        .for_each(|(out, plane)| {
            for (r, row) in out.chunks_mut(h * w).enumerate() {
                let (ky, kx) = (r / k, r % k);
                // output column x reads input column x + kx - p where that is inside
                let lo = p.saturating_sub(kx);
                let hi = (w + p).saturating_sub(kx).min(w);
                for y in 0..h {
                    let Some(sy) = (y + ky).checked_sub(p).filter(|&sy| sy < h) else {
                        continue;
                    };
                    let src = &plane[sy * w..(sy + 1) * w];
                    if lo < hi {
                        row[y * w + lo..y * w + hi].copy_from_slice(&src[lo + kx - p..hi + kx - p]);
                    }
                }
            }
        });
    cols
}

/// `nn.ConvTranspose2d(cin, cout, 2, stride=2)` on one image: each input pixel becomes a
/// 2 x 2 block, y[o, 2i + a, 2j + b] = sum_c x[c, i, j] w[c, o, a, b] + bias[o].
struct Up {
    /// (cout 2 2, cin)
    weight: Tensor,
    bias: Tensor,
}

impl Up {
    fn new(w: &mut Weights, name: &str, cin: usize, cout: usize) -> MResult<Self> {
        Ok(Up {
            weight: w
                .take(&format!("{name}.weight"), &[cin, cout, 2, 2])?
                .reshape((cin, cout * 4))?
                .t()?
                .contiguous()?,
            bias: w
                .take(&format!("{name}.bias"), &[cout])?
                .reshape((1, cout, 1, 1))?,
        })
    }

    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let (b, cin, h, w) = x.dims4()?;
        let cout = self.weight.dim(0)? / 4;
        self.weight
            .matmul(&x.reshape((b * cin, h * w))?)? // (cout 2 2, H W)
            .reshape((cout, 2, 2, h, w))?
            .permute((0, 3, 1, 4, 2))? // (cout, H, 2, W, 2)
            .reshape((b, cout, 2 * h, 2 * w))?
            .broadcast_add(&self.bias)
    }
}

/// `nn.GroupNorm(groups, c)` with affine weight and bias, followed by the ReLU that always
/// follows it in model.py, in two passes over the data (statistics, then output).
struct GroupNorm {
    weight: Vec<f32>,
    bias: Vec<f32>,
    groups: usize,
}

impl GroupNorm {
    fn new(w: &mut Weights, name: &str, groups: usize, c: usize) -> MResult<Self> {
        Ok(GroupNorm {
            weight: w.take(&format!("{name}.weight"), &[c])?.to_vec1()?,
            bias: w.take(&format!("{name}.bias"), &[c])?.to_vec1()?,
            groups,
        })
    }

    /// relu((x - mean) / sqrt(var + eps) weight + bias), mean and (biased) variance per
    /// image and group.
    fn forward_relu(&self, x: &Tensor) -> Result<Tensor> {
        let (b, c, h, wd) = x.dims4()?;
        let per_channel = h * wd;
        let per_group = c / self.groups * per_channel;
        let mut v = x.flatten_all()?.to_vec1::<f32>()?;
        v.par_chunks_mut(per_group)
            .enumerate()
            .for_each(|(g, group)| {
                let n = group.len() as f64;
                let mean = group.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
                let var = group
                    .iter()
                    .map(|&v| (f64::from(v) - mean).powi(2))
                    .sum::<f64>()
                    / n;
                let inv = 1.0 / (var + GN_EPS).sqrt();
                for (j, channel) in group.chunks_mut(per_channel).enumerate() {
                    let ch = (g % self.groups) * (c / self.groups) + j;
                    let scale = inv * f64::from(self.weight[ch]);
                    let shift = f64::from(self.bias[ch]) - mean * scale;
                    let (scale, shift) = (scale as f32, shift as f32);
                    for v in channel {
                        *v = (*v * scale + shift).max(0.0);
                    }
                }
            });
        Tensor::from_vec(v, (b, c, h, wd), x.device())
    }
}

/// model.py's `block`: two 3x3 convolutions with group norm and ReLU (indices 0, 1, 3, 4
/// of its `nn.Sequential`).
struct Block {
    conv1: Conv,
    norm1: GroupNorm,
    conv2: Conv,
    norm2: GroupNorm,
}

/// The greatest common divisor, for `math.gcd(cout, 8)`.
fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a } else { gcd(b, a % b) }
}

impl Block {
    fn new(w: &mut Weights, name: &str, cin: usize, cout: usize) -> MResult<Self> {
        let groups = gcd(cout, 8);
        Ok(Block {
            conv1: Conv::new(w, &format!("{name}.0"), cin, cout, 3)?,
            norm1: GroupNorm::new(w, &format!("{name}.1"), groups, cout)?,
            conv2: Conv::new(w, &format!("{name}.3"), cout, cout, 3)?,
            norm2: GroupNorm::new(w, &format!("{name}.4"), groups, cout)?,
        })
    }

    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let x = self.norm1.forward_relu(&self.conv1.forward(x)?)?;
        self.norm2.forward_relu(&self.conv2.forward(&x)?)
    }
}

/// `Encoder`: `levels` blocks, each but the last followed by 2x2 max pooling.
struct Encoder {
    blocks: Vec<Block>,
    channels: Vec<usize>,
}

impl Encoder {
    fn new(w: &mut Weights, name: &str, cin: usize, cfg: &NetsConfig) -> MResult<Self> {
        let channels: Vec<usize> = (0..cfg.levels).map(|i| cfg.width << i).collect();
        let mut blocks = Vec::new();
        for (i, &c) in channels.iter().enumerate() {
            let prev = if i == 0 { cin } else { channels[i - 1] };
            blocks.push(Block::new(w, &format!("{name}.blocks.{i}"), prev, c)?);
        }
        Ok(Encoder { blocks, channels })
    }

    /// Every level's features.
    fn forward(&self, x: &Tensor) -> Result<Vec<Tensor>> {
        let mut feats: Vec<Tensor> = Vec::with_capacity(self.blocks.len());
        for (i, b) in self.blocks.iter().enumerate() {
            let input = match feats.last() {
                None => x.clone(),
                Some(f) => f.max_pool2d(2)?,
            };
            debug_assert!(i == feats.len());
            feats.push(b.forward(&input)?);
        }
        Ok(feats)
    }
}

/// `NormalsNet`: a U-Net, (1, 3, H, W) -> unit normals (1, H, W, 3) and mask logits (1, H, W).
pub(super) struct NormalsNet {
    enc: Encoder,
    up: Vec<Up>,
    dec: Vec<Block>,
    head: Conv,
}

impl NormalsNet {
    pub(super) fn new(w: &mut Weights, cfg: &NetsConfig) -> MResult<Self> {
        let enc = Encoder::new(w, "normals.enc", 3, cfg)?;
        let ch = enc.channels.clone();
        let mut up = Vec::new();
        let mut dec = Vec::new();
        for i in 0..ch.len() - 1 {
            up.push(Up::new(w, &format!("normals.up.{i}"), ch[i + 1], ch[i])?);
            dec.push(Block::new(
                w,
                &format!("normals.dec.{i}"),
                2 * ch[i],
                ch[i],
            )?);
        }
        let head = Conv::new(w, "normals.head", ch[0], 4, 1)?;
        Ok(NormalsNet { enc, up, dec, head })
    }

    pub(super) fn forward(&self, x: &Tensor) -> Result<(Tensor, Tensor)> {
        let feats = self.enc.forward(x)?;
        let mut y = feats[feats.len() - 1].clone();
        for i in (0..self.dec.len()).rev() {
            let upsampled = self.up[i].forward(&y)?;
            y = self.dec[i].forward(&Tensor::cat(&[&upsampled, &feats[i]], 1)?)?;
        }
        let out = self.head.forward(&y)?.permute((0, 2, 3, 1))?; // (1, H, W, 4)
        // the bias towards +z of model.py
        let plus_z = Tensor::new(&[0f32, 0.0, 1.0], out.device())?;
        let n = out.narrow(D::Minus1, 0, 3)?.broadcast_add(&plus_z)?;
        // F.normalize(n, dim=-1, eps=1e-6)
        let len = n
            .sqr()?
            .sum_keepdim(D::Minus1)?
            .sqrt()?
            .clamp(1e-6f32, f32::MAX)?;
        let logits = out.narrow(D::Minus1, 3, 1)?.squeeze(D::Minus1)?;
        Ok((n.broadcast_div(&len)?, logits))
    }
}

/// `GlobalNet`: an encoder on image and mask, pooled over the object and the whole image,
/// and a two-layer head.
pub(super) struct GlobalNet {
    enc: Encoder,
    /// The encoder's downsampling factor, 2^(levels - 1).
    factor: usize,
    lin1: (Tensor, Tensor),
    lin2: (Tensor, Tensor),
}

impl GlobalNet {
    pub(super) fn new(w: &mut Weights, name: &str, cfg: &NetsConfig, nout: usize) -> MResult<Self> {
        let enc = Encoder::new(w, &format!("{name}.enc"), 4, cfg)?;
        let c = enc.channels[enc.channels.len() - 1];
        let lin = |w: &mut Weights, i: usize, cin: usize, cout: usize| -> MResult<_> {
            Ok((
                w.take(&format!("{name}.head.{i}.weight"), &[cout, cin])?
                    .t()?
                    .contiguous()?,
                w.take(&format!("{name}.head.{i}.bias"), &[cout])?,
            ))
        };
        let lin1 = lin(w, 0, 2 * c, 4 * c)?;
        let lin2 = lin(w, 2, 4 * c, nout)?;
        Ok(GlobalNet {
            enc,
            factor: 1 << (cfg.levels - 1),
            lin1,
            lin2,
        })
    }

    /// x (1, 3, H, W), mask (1, 1, H, W) as 0 and 1 -> (1, nout).
    pub(super) fn forward(&self, x: &Tensor, mask: &Tensor) -> Result<Tensor> {
        let feats = self.enc.forward(&Tensor::cat(&[x, mask], 1)?)?;
        let f = &feats[feats.len() - 1];
        // adaptive_avg_pool2d to f's size: H and W are multiples of the factor
        let mf = mask.avg_pool2d(self.factor)?;
        let area = mf
            .sum_keepdim((2, 3))?
            .clamp(1e-6f32, f32::MAX)?
            .flatten_from(1)?;
        let on_object = f
            .broadcast_mul(&mf)?
            .sum_keepdim((2, 3))?
            .flatten_from(1)?
            .broadcast_div(&area)?;
        let mean = f.mean_keepdim((2, 3))?.flatten_from(1)?;
        let h = Tensor::cat(&[&on_object, &mean], 1)?;
        let h = h
            .matmul(&self.lin1.0)?
            .broadcast_add(&self.lin1.1)?
            .relu()?;
        h.matmul(&self.lin2.0)?.broadcast_add(&self.lin2.1)
    }
}
