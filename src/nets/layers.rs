//! The layers of model.py, named as its modules are (`block`, `Encoder`, `NormalsNet`,
//! `GlobalNet`), each built from its tensors in a [`Weights`], on one image's [`Planes`].

use rayon::prelude::*;

use super::planes::{Planes, matmul};
use super::weights::{NetsConfig, Weights};
use crate::error::Result as MResult;

/// GroupNorm's epsilon (PyTorch's default).
const GN_EPS: f64 = 1e-5;

/// `nn.Conv2d` (stride 1, padding k / 2) with bias, as a matrix product of the flattened
/// kernel (cout, cin k k) and the image's k x k neighbourhoods (cin k k, H W).
struct Conv {
    /// (cout, cin k k)
    weight: Vec<f32>,
    bias: Vec<f32>,
    cin: usize,
    k: usize,
}

impl Conv {
    fn new(w: &mut Weights, name: &str, cin: usize, cout: usize, k: usize) -> MResult<Self> {
        Ok(Conv {
            weight: w.take(&format!("{name}.weight"), &[cout, cin, k, k])?,
            bias: w.take(&format!("{name}.bias"), &[cout])?,
            cin,
            k,
        })
    }

    fn forward(&self, x: &Planes) -> Planes {
        assert_eq!(x.c, self.cin, "conv: input channels");
        let (k, p, area) = (self.k, self.k / 2, x.area());
        let cout = self.bias.len();
        let ckk = self.cin * k * k;
        let mut y = if k == 1 {
            matmul(&self.weight, false, &x.v, cout, ckk, area)
        } else {
            let cols = im2col(&x.v, self.cin, x.h, x.w, k, p);
            matmul(&self.weight, false, &cols, cout, ckk, area)
        };
        add_bias(&mut y, &self.bias);
        Planes::new(cout, x.h, x.w, y)
    }
}

/// Adds `bias[o]` to plane o of `y` (one plane per bias value).
fn add_bias(y: &mut [f32], bias: &[f32]) {
    let area = y.len() / bias.len();
    for (plane, &b) in y.chunks_mut(area).zip(bias) {
        plane.iter_mut().for_each(|v| *v += b);
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

/// `nn.ConvTranspose2d(cin, cout, 2, stride=2)`: each input pixel becomes a 2 x 2 block,
/// y[o, 2i + a, 2j + b] = sum_c x[c, i, j] w[c, o, a, b] + bias[o].
struct Up {
    /// (cin, cout 2 2), as stored
    weight: Vec<f32>,
    bias: Vec<f32>,
    cin: usize,
}

impl Up {
    fn new(w: &mut Weights, name: &str, cin: usize, cout: usize) -> MResult<Self> {
        Ok(Up {
            weight: w.take(&format!("{name}.weight"), &[cin, cout, 2, 2])?,
            bias: w.take(&format!("{name}.bias"), &[cout])?,
            cin,
        })
    }

    fn forward(&self, x: &Planes) -> Planes {
        assert_eq!(x.c, self.cin, "up: input channels");
        let (h, w, cout) = (x.h, x.w, self.bias.len());
        // (cout 2 2, H W): the stored weight read transposed
        let y4 = matmul(&self.weight, true, &x.v, cout * 4, self.cin, h * w);
        let mut y = vec![0f32; cout * 4 * h * w];
        for (o, block) in y4.chunks_exact(4 * h * w).enumerate() {
            let out = &mut y[o * 4 * h * w..(o + 1) * 4 * h * w];
            for (ab, src) in block.chunks_exact(h * w).enumerate() {
                let (a, b) = (ab / 2, ab % 2);
                for i in 0..h {
                    for j in 0..w {
                        out[(2 * i + a) * 2 * w + 2 * j + b] = src[i * w + j] + self.bias[o];
                    }
                }
            }
        }
        Planes::new(cout, 2 * h, 2 * w, y)
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
            weight: w.take(&format!("{name}.weight"), &[c])?,
            bias: w.take(&format!("{name}.bias"), &[c])?,
            groups,
        })
    }

    /// relu((x - mean) / sqrt(var + eps) weight + bias), mean and (biased) variance per
    /// group.
    fn forward_relu(&self, mut x: Planes) -> Planes {
        let c = x.c;
        let per_channel = x.area();
        let per_group = c / self.groups * per_channel;
        x.v.par_chunks_mut(per_group)
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
                    let ch = g * (c / self.groups) + j;
                    let scale = inv * f64::from(self.weight[ch]);
                    let shift = f64::from(self.bias[ch]) - mean * scale;
                    let (scale, shift) = (scale as f32, shift as f32);
                    for v in channel {
                        *v = (*v * scale + shift).max(0.0);
                    }
                }
            });
        x
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

    fn forward(&self, x: &Planes) -> Planes {
        let x = self.norm1.forward_relu(self.conv1.forward(x));
        self.norm2.forward_relu(self.conv2.forward(&x))
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
    fn forward(&self, x: &Planes) -> Vec<Planes> {
        let mut feats: Vec<Planes> = Vec::with_capacity(self.blocks.len());
        for b in &self.blocks {
            let f = match feats.last() {
                None => b.forward(x),
                Some(f) => b.forward(&f.max_pool2()),
            };
            feats.push(f);
        }
        feats
    }
}

/// `NormalsNet`: a U-Net, 3 planes -> unit normals (H W of xyz) and mask logits (H W).
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

    pub(super) fn forward(&self, x: &Planes) -> (Vec<[f32; 3]>, Vec<f32>) {
        let mut feats = self.enc.forward(x);
        let mut y = feats.pop().expect("at least one level");
        for i in (0..self.dec.len()).rev() {
            y = self.dec[i].forward(&self.up[i].forward(&y).cat(&feats[i]));
        }
        let out = self.head.forward(&y);
        let normals = (0..out.area())
            .map(|i| {
                // the bias towards +z of model.py, then F.normalize(n, dim=-1, eps=1e-6)
                let n = [
                    out.v[i],
                    out.v[out.area() + i],
                    out.v[2 * out.area() + i] + 1.0,
                ];
                let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt().max(1e-6);
                n.map(|v| v / len)
            })
            .collect();
        (normals, out.plane(3).to_vec())
    }
}

/// `GlobalNet`: an encoder on image and mask, pooled over the object and the whole image,
/// and a two-layer head.
pub(super) struct GlobalNet {
    enc: Encoder,
    /// The encoder's downsampling factor, 2^(levels - 1).
    factor: usize,
    /// (weight (cout, cin), bias) of the head's two linear layers.
    lin1: (Vec<f32>, Vec<f32>),
    lin2: (Vec<f32>, Vec<f32>),
}

impl GlobalNet {
    pub(super) fn new(w: &mut Weights, name: &str, cfg: &NetsConfig, nout: usize) -> MResult<Self> {
        let enc = Encoder::new(w, &format!("{name}.enc"), 4, cfg)?;
        let c = enc.channels[enc.channels.len() - 1];
        let lin = |w: &mut Weights, i: usize, cin: usize, cout: usize| -> MResult<_> {
            Ok((
                w.take(&format!("{name}.head.{i}.weight"), &[cout, cin])?,
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

    /// x (3 planes), mask (1 plane of 0 and 1) -> nout values.
    pub(super) fn forward(&self, x: &Planes, mask: &Planes) -> Vec<f32> {
        let feats = self.enc.forward(&x.cat(mask));
        let f = &feats[feats.len() - 1];
        // adaptive_avg_pool2d to f's size: H and W are multiples of the factor
        let mf = mask.avg_pool(self.factor);
        let area = mf.v.iter().sum::<f32>().max(1e-6);
        let on_object = (0..f.c).map(|ci| {
            let sum: f32 = f.plane(ci).iter().zip(&mf.v).map(|(a, b)| a * b).sum();
            sum / area
        });
        let mean = (0..f.c).map(|ci| f.plane(ci).iter().sum::<f32>() / f.area() as f32);
        let h: Vec<f32> = on_object.chain(mean).collect();
        let h: Vec<f32> = linear(&self.lin1, &h)
            .into_iter()
            .map(|v| v.max(0.0))
            .collect();
        linear(&self.lin2, &h)
    }
}

/// `nn.Linear` on one vector: weight (cout, cin) times x, plus bias.
fn linear((weight, bias): &(Vec<f32>, Vec<f32>), x: &[f32]) -> Vec<f32> {
    let mut y = matmul(weight, false, x, bias.len(), x.len(), 1);
    y.iter_mut().zip(bias).for_each(|(y, b)| *y += b);
    y
}
