//! The fast path's passes over a prepared scene: the lobe plan, the texel table and the
//! pixel records, the kernels run over chunks of pixels in parallel, and the chunks' sums
//! added in a fixed order.

use rayon::prelude::*;

use super::FastCpu;
use super::backward::{Backward, TEXEL_SUMS};
use super::dense::{Dense, DenseBackward, DenseForward};
use super::forward::Forward;
use super::pair::Setup;
use super::table::{self, LobePlan, TexelTable, depends_on_x, has_scale};
use crate::Jacobian;
use crate::material::{N_PARAMS, idx};
use crate::prepare::Prepared;
use crate::scene::{Gradients, Wanted};
use crate::spline::spline_basis;

/// Pixels per task of the forward pass.
const FORWARD_CHUNK: usize = 64;
/// Pixels per call of the backward kernel (its texel sums run over these in f32).
const BACKWARD_CHUNK: usize = 256;
/// Most chunks of the backward pass, each with its own per-texel sums. Each chunk's sums
/// are fresh memory that a new process pays page faults for (measured: 13 chunks of a
/// 64 x 128 map cost a `grad` process 60-90 ms of system time), so few large chunks.
const MAX_CHUNKS: usize = 8;
/// Pixels per backward chunk below which fewer chunks are used: small enough that the
/// photo editor's refinement (at most 2,048 object pixels, 512 texels) runs on every core
/// (4,096 ran it on one: a 128 x 128 photo's 20 steps took 8.3 s with one core of two
/// busy), large enough that a chunk's pixels cost more than its texel sums' memory.
const MIN_CHUNK_PIXELS: usize = 512;
/// Memory for the per-chunk texel sums of the backward pass.
const CHUNK_MEMORY: usize = 256 << 20;
impl FastCpu {
    /// The image of a prepared scene, row-major, 0 on background pixels.
    pub fn forward(&self, prep: &Prepared) -> Vec<[f32; 3]> {
        let (sums, _) = self.forward_sums(prep, false);
        let mut image = vec![[0.0f32; 3]; prep.width * prep.height];
        for (p, v) in prep.pixels.iter().zip(sums) {
            image[p.index] = v.map(|x| x as f32);
        }
        image
    }

    /// dI^k/dn per pixel of `prep.pixels` (in that order), `[k][axis]`, in one pass that
    /// costs little more than the forward one. With `backward` (upstream `g`, row-major,
    /// and the gradients wanted), [`FastCpu::backward`] too: the Jacobian then comes from
    /// the backward pass's own lobe terms (orthographic cameras; a perspective one gets
    /// its own pass).
    pub fn normal_jacobians(
        &self,
        prep: &Prepared,
        backward: Option<(&[[f32; 3]], Wanted)>,
    ) -> (Vec<Jacobian>, Option<Gradients>) {
        match backward {
            None => {
                let (_, jac) = self.forward_sums(prep, true);
                (jac.iter().map(jacobian_f32).collect(), None)
            }
            Some((g, wanted)) if !prep.camera.is_orthographic() => {
                let grads = self.backward(prep, g, wanted);
                (self.normal_jacobians(prep, None).0, Some(grads))
            }
            Some((g, wanted)) => {
                let (grads, jac) = self.backward_pass(prep, g, wanted, true);
                (jac, Some(grads))
            }
        }
    }

    /// Per pixel of `prep.pixels`: the image's f64 sums, and with `jacobian` dI^k/dn's.
    fn forward_sums(&self, prep: &Prepared, jacobian: bool) -> (Vec<[f64; 3]>, Vec<[f64; 9]>) {
        let perspective = !prep.camera.is_orthographic();
        let ctrl = &prep.ctrl;
        // orthographic: constant lobes are summed per texel in the table; perspective:
        // evaluated per pair without x^m1
        let plan = if perspective {
            LobePlan::new(ctrl, |k, s| has_scale(ctrl, k, s))
        } else {
            LobePlan::new(ctrl, |k, s| depends_on_x(ctrl, k, s))
        };
        let consts: Vec<(usize, usize)> = (0..3)
            .flat_map(|k| (0..3).map(move |s| (k, s)))
            .filter(|&(k, s)| has_scale(ctrl, k, s) && !depends_on_x(ctrl, k, s))
            .collect();
        let table = TexelTable::new(prep, &prep.lit, &plan.columns(), &[], &consts);
        let dense = Dense::of(&plan, ctrl).filter(|_| self.dense && !perspective && !jacobian);
        let inputs = PassInputs::new(prep, plan);
        let (setup, px) = (inputs.setup(), &inputs.px);
        let mut sums = vec![[0.0f64; 3]; px.len()];
        if let Some(dense) = dense {
            let records = dense.records(&table, self.lanes());
            px.par_chunks(FORWARD_CHUNK)
                .zip(sums.par_chunks_mut(FORWARD_CHUNK))
                .for_each(|(px, out)| {
                    self.dispatch(DenseForward {
                        dense: &dense,
                        records: &records,
                        px,
                        out,
                    })
                });
            return (sums, Vec::new());
        }
        let mut jac = vec![[0.0f64; 9]; if jacobian { px.len() } else { 0 }];
        let jac_chunks: Vec<Option<&mut [[f64; 9]]>> = if jacobian {
            jac.chunks_mut(FORWARD_CHUNK).map(Some).collect()
        } else {
            (0..px.len().div_ceil(FORWARD_CHUNK))
                .map(|_| None)
                .collect()
        };
        px.par_chunks(FORWARD_CHUNK)
            .zip(sums.par_chunks_mut(FORWARD_CHUNK))
            .zip(jac_chunks)
            .for_each(|((px, out), jac)| {
                self.dispatch(Forward {
                    table: &table,
                    setup: &setup,
                    px,
                    out,
                    jac,
                })
            });
        (sums, jac)
    }

    /// The backward pass of a prepared scene for upstream `g` (row-major), for the
    /// gradients `wanted` asks for; the others are zeros. Without dLoss/dL only the lit
    /// texels are visited (every other term is a multiple of the radiance), without
    /// dLoss/dctrl only the lobes with a scale (the others add nothing to the image), and
    /// the terms of what is not wanted are left out.
    pub fn backward(&self, prep: &Prepared, g: &[[f32; 3]], wanted: Wanted) -> Gradients {
        self.backward_pass(prep, g, wanted, false).0
    }

    /// The backward pass, with the Jacobian per pixel of `prep.pixels` if `jacobian`
    /// (orthographic cameras only; else empty).
    fn backward_pass(
        &self,
        prep: &Prepared,
        g: &[[f32; 3]],
        wanted: Wanted,
        jacobian: bool,
    ) -> (Gradients, Vec<Jacobian>) {
        let perspective = !prep.camera.is_orthographic();
        let ctrl = &prep.ctrl;
        // dLoss/dctrl: every lobe (a lobe whose scale is 0 still has a gradient for its
        // scale); else the lobes that add to the image
        let plan = if wanted.ctrl {
            LobePlan::new(ctrl, |_, _| true)
        } else {
            LobePlan::new(ctrl, |k, s| has_scale(ctrl, k, s))
        };
        let texels: Vec<usize> = if wanted.env {
            (0..prep.texels.len()).collect()
        } else {
            prep.lit.clone()
        };
        // an orthographic scene: the dense kernels, with every lobe where the material
        // shares a little (see `Dense::for_backward`), whichever gradients are wanted (they
        // sum every gradient in registers at little more than the cost of one; measured on
        // a nine-lobe material, dLoss/dn alone or dLoss/dL and dLoss/dctrl alone by the
        // plan kernels took longer than all three by the dense ones)
        let dense = (self.dense && !perspective)
            .then(|| Dense::for_backward(&plan, ctrl))
            .flatten();
        let columns = match &dense {
            Some(d) => d.columns(),
            None => plan.columns(),
        };
        let table = TexelTable::new(prep, &texels, &columns, &plan.const_columns(), &[]);
        let records = dense
            .as_ref()
            .map(|d| d.records(&table, self.lanes()))
            .unwrap_or_default();
        let inputs = PassInputs::new(prep, plan);
        let (setup, px) = (inputs.setup(), &inputs.px);
        let gp: Vec<[f32; 3]> = prep.pixels.iter().map(|p| g[p.index]).collect();
        let n_tex = table.len;
        // the number of chunks depends on the problem size only, never on the threads
        let by_memory = (CHUNK_MEMORY / (n_tex.max(1) * TEXEL_SUMS * 8)).max(1);
        let n_chunks = px
            .len()
            .div_ceil(MIN_CHUNK_PIXELS)
            .clamp(1, MAX_CHUNKS)
            .min(by_memory);
        let per_chunk = px.len().div_ceil(n_chunks).max(1);
        struct Part {
            dn: Vec<[f64; 3]>,
            jac: Vec<[f64; 9]>,
            tex: Vec<f64>,
            ctrl: [f64; N_PARAMS],
        }
        let parts: Vec<Part> = px
            .par_chunks(per_chunk)
            .zip(gp.par_chunks(per_chunk))
            .map(|(px, gp)| {
                let mut part = Part {
                    dn: vec![[0.0; 3]; px.len()],
                    jac: vec![[0.0; 9]; if jacobian { px.len() } else { 0 }],
                    tex: vec![0.0; n_tex * TEXEL_SUMS],
                    ctrl: [0.0; N_PARAMS],
                };
                let mut jacs = part.jac.chunks_mut(BACKWARD_CHUNK);
                for ((px, gp), dn) in px
                    .chunks(BACKWARD_CHUNK)
                    .zip(gp.chunks(BACKWARD_CHUNK))
                    .zip(part.dn.chunks_mut(BACKWARD_CHUNK))
                {
                    let jac = jacs.next();
                    match &dense {
                        Some(dense) => self.dispatch(DenseBackward {
                            dense,
                            records: &records,
                            n_texels: n_tex,
                            px,
                            g: gp,
                            dn,
                            tex: &mut part.tex,
                            jac,
                        }),
                        None => self.dispatch(Backward {
                            table: &table,
                            setup: &setup,
                            px,
                            g: gp,
                            dn,
                            tex: &mut part.tex,
                            ctrl: &mut part.ctrl,
                            wanted,
                            jac,
                        }),
                    }
                }
                part
            })
            .collect();
        // fixed-order reduction over chunks
        let mut tex = vec![0.0f64; n_tex * TEXEL_SUMS];
        let mut d_ctrl = [0.0f64; N_PARAMS];
        let mut dn = Vec::with_capacity(px.len());
        let mut jac = Vec::with_capacity(if jacobian { px.len() } else { 0 });
        for part in parts {
            jac.extend(part.jac.iter().map(jacobian_f32));
            for (a, b) in tex.iter_mut().zip(&part.tex) {
                *a += b;
            }
            for (a, b) in d_ctrl.iter_mut().zip(&part.ctrl) {
                *a += b;
            }
            dn.extend(part.dn);
        }
        let mut d_env = vec![[0.0f32; 3]; prep.env_height * prep.env_width];
        for (i, &ti) in table.src.iter().enumerate() {
            let t = &prep.texels[ti];
            let sums = &tex[i * TEXEL_SUMS..(i + 1) * TEXEL_SUMS];
            d_env[t.index] = [0, 1, 2].map(|k| (sums[k] * t.d_omega) as f32);
            if !perspective {
                let basis = spline_basis(t.theta_d);
                for k in 0..3 {
                    for s in 0..3 {
                        for tt in 0..2 {
                            let v = sums[3 + (k * 3 + s) * 2 + tt];
                            for (j, bj) in basis.iter().enumerate() {
                                d_ctrl[idx(k, s, tt, j)] += v * bj;
                            }
                        }
                    }
                }
            }
        }
        let mut d_normals = vec![[0.0f32; 3]; prep.width * prep.height];
        for (p, v) in prep.pixels.iter().zip(dn) {
            d_normals[p.index] = v.map(|x| x as f32);
        }
        let mut grads = Gradients {
            d_env,
            d_normals,
            d_ctrl: d_ctrl.map(|x| x as f32),
        };
        grads.keep(wanted);
        (grads, jac)
    }
}

/// A pixel's f64 sums of dI^k/dn (index k * 3 + axis) as its Jacobian.
fn jacobian_f32(j: &[f64; 9]) -> Jacobian {
    std::array::from_fn(|k| std::array::from_fn(|a| j[k * 3 + a] as f32))
}

/// What a pass reads besides the texel table.
struct PassInputs {
    plan: LobePlan,
    ctrl: [f32; N_PARAMS],
    perspective: bool,
    px: Vec<table::Px>,
}

impl PassInputs {
    fn new(prep: &Prepared, plan: LobePlan) -> Self {
        PassInputs {
            plan,
            ctrl: kernel_ctrl(&prep.ctrl),
            perspective: !prep.camera.is_orthographic(),
            px: table::pixels(prep),
        }
    }

    fn setup(&self) -> Setup<'_> {
        Setup {
            plan: &self.plan,
            ctrl: &self.ctrl,
            perspective: self.perspective,
        }
    }
}

/// The control points as the kernels read them: f32, scales times log2(e) (see
/// [`table::column_scale`]).
fn kernel_ctrl(ctrl: &[f64; N_PARAMS]) -> [f32; N_PARAMS] {
    std::array::from_fn(|i| {
        (ctrl[i] * table::column_scale(i / crate::spline::N_CTRL_POINTS)) as f32
    })
}
