//! The fast CPU path: the layer in f32 with explicit SIMD and rayon threads.
//!
//! One generic kernel per pass ([`forward`], [`backward`]), written on `pulp`'s `Simd`
//! trait and instantiated at run time for the widest instruction set the CPU has:
//! AVX-512 (16 lanes), AVX2 + FMA (8), NEON (4) or a scalar fallback. Texels sit in SIMD
//! lanes, tile-ordered so that a block below a pixel's horizon is skipped whole; one pixel
//! is broadcast against each block. The per-texel work of the f64 preparation is reused,
//! and the material is reduced to the lobe terms the scene needs ([`table::LobePlan`]).
//!
//! Deterministic: pixels are cut into chunks whose number depends on the problem size
//! only, every sum runs in a fixed order, and partial sums of the backward pass are
//! added in f64 in chunk order; results are bitwise equal for any thread count.
//! Memory is O(pixels + texels x chunks).

pub mod backward;
pub mod forward;
pub mod math;
pub mod pair;
pub mod table;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::material::N_PARAMS;
use crate::prepare::Prepared;
use crate::scene::{Gradients, Image, Wanted};
use crate::spline::spline_basis;
use crate::{Backend, material::idx};

use backward::{Backward, TEXEL_SUMS};
use forward::Forward;
use pair::Setup;
use table::{LobePlan, TexelTable, depends_on_x, has_scale};

/// Pixels per task of the forward pass.
const FORWARD_CHUNK: usize = 64;
/// Pixels per call of the backward kernel (its texel sums run over these in f32).
const BACKWARD_CHUNK: usize = 256;
/// Most chunks of the backward pass, each with its own per-texel sums. Each chunk's sums
/// are fresh memory that a new process pays page faults for (measured: 13 chunks of a
/// 64 x 128 map cost a `grad` process 60-90 ms of system time), so few large chunks.
const MAX_CHUNKS: usize = 8;
/// Pixels per backward chunk below which fewer chunks are used.
const MIN_CHUNK_PIXELS: usize = 4096;
/// Memory for the per-chunk texel sums of the backward pass.
const CHUNK_MEMORY: usize = 256 << 20;

/// An instruction set the fast path can run on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SimdLevel {
    /// x86-64 AVX-512 (F, BW, CD, DQ, VL): 16 f32 lanes.
    Avx512,
    /// x86-64 AVX2 with FMA: 8 lanes.
    Avx2,
    /// aarch64 NEON: 4 lanes.
    Neon,
    /// Portable scalar code: 1 lane.
    Scalar,
}

impl SimdLevel {
    /// All levels, widest first.
    pub const ALL: [SimdLevel; 4] = [
        SimdLevel::Avx512,
        SimdLevel::Avx2,
        SimdLevel::Neon,
        SimdLevel::Scalar,
    ];

    /// The name used by `MATEDIT_SIMD` and in descriptions.
    pub fn name(self) -> &'static str {
        match self {
            SimdLevel::Avx512 => "avx512",
            SimdLevel::Avx2 => "avx2",
            SimdLevel::Neon => "neon",
            SimdLevel::Scalar => "scalar",
        }
    }

    /// pulp's handle for this level, if this CPU has it.
    fn arch(self) -> Option<pulp::Arch> {
        #[cfg(target_arch = "x86_64")]
        {
            match self {
                SimdLevel::Avx512 => pulp::x86::V4::try_new().map(pulp::Arch::V4),
                SimdLevel::Avx2 => pulp::x86::V3::try_new().map(pulp::Arch::V3),
                SimdLevel::Neon => None,
                SimdLevel::Scalar => Some(pulp::Arch::Scalar),
            }
        }
        #[cfg(target_arch = "aarch64")]
        {
            match self {
                SimdLevel::Neon => pulp::aarch64::Neon::try_new().map(pulp::Arch::Neon),
                SimdLevel::Scalar => Some(pulp::Arch::Scalar),
                _ => None,
            }
        }
        #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
        {
            match self {
                SimdLevel::Scalar => Some(pulp::Arch::Scalar),
                _ => None,
            }
        }
    }

    /// Whether this CPU can run this level.
    pub fn available(self) -> bool {
        self.arch().is_some()
    }
}

/// The fast CPU path as a [`Backend`].
#[derive(Clone, Copy, Debug)]
pub struct FastCpu {
    level: SimdLevel,
    arch: pulp::Arch,
}

impl FastCpu {
    /// The widest level this CPU has, or the one `MATEDIT_SIMD` names (avx512, avx2, neon
    /// or scalar; an error if it is unknown or this CPU lacks it).
    pub fn new() -> Result<Self> {
        match std::env::var("MATEDIT_SIMD") {
            Ok(name) if !name.is_empty() => {
                let level = SimdLevel::ALL
                    .into_iter()
                    .find(|l| l.name() == name)
                    .ok_or_else(|| {
                        Error::Invalid(format!(
                            "MATEDIT_SIMD: unknown level '{name}': expected avx512, avx2, neon or scalar"
                        ))
                    })?;
                Self::with_level(level)
                    .ok_or_else(|| Error::Invalid(format!("MATEDIT_SIMD: this CPU has no {name}")))
            }
            _ => Ok(Self::best()),
        }
    }

    /// The widest level this CPU has.
    pub fn best() -> Self {
        SimdLevel::ALL
            .into_iter()
            .find_map(Self::with_level)
            .expect("the scalar level is always available")
    }

    /// The fast path at `level`, if this CPU has it.
    pub fn with_level(level: SimdLevel) -> Option<Self> {
        level.arch().map(|arch| FastCpu { level, arch })
    }

    /// The level it runs at.
    pub fn level(&self) -> SimdLevel {
        self.level
    }

    /// Runs a SIMD operation at this level.
    fn dispatch<Op: pulp::WithSimd>(&self, op: Op) -> Op::Output {
        self.arch.dispatch(op)
    }

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
    /// costs little more than the forward one.
    pub fn normal_jacobians(&self, prep: &Prepared) -> Vec<[[f32; 3]; 3]> {
        let (_, jac) = self.forward_sums(prep, true);
        jac.iter()
            .map(|j| std::array::from_fn(|k| std::array::from_fn(|a| j[k * 3 + a] as f32)))
            .collect()
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
        let inputs = PassInputs::new(prep, plan);
        let (setup, px) = (inputs.setup(), &inputs.px);
        let mut sums = vec![[0.0f64; 3]; px.len()];
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

    /// The backward pass of a prepared scene for upstream `g` (row-major).
    pub fn backward(&self, prep: &Prepared, g: &[[f32; 3]]) -> Gradients {
        self.backward_wanted(prep, g, Wanted::ALL)
    }

    /// The backward pass for the gradients `wanted` asks for; the others are zeros.
    /// Without dLoss/dL only the lit texels are visited (every other term is a multiple of
    /// the radiance), without dLoss/dctrl only the lobes with a scale (the others add
    /// nothing to the image), and the terms of what is not wanted are left out.
    pub fn backward_wanted(&self, prep: &Prepared, g: &[[f32; 3]], wanted: Wanted) -> Gradients {
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
        let table = TexelTable::new(prep, &texels, &plan.columns(), &plan.const_columns(), &[]);
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
            tex: Vec<f64>,
            ctrl: [f64; N_PARAMS],
        }
        let parts: Vec<Part> = px
            .par_chunks(per_chunk)
            .zip(gp.par_chunks(per_chunk))
            .map(|(px, gp)| {
                let mut part = Part {
                    dn: vec![[0.0; 3]; px.len()],
                    tex: vec![0.0; n_tex * TEXEL_SUMS],
                    ctrl: [0.0; N_PARAMS],
                };
                for ((px, gp), dn) in px
                    .chunks(BACKWARD_CHUNK)
                    .zip(gp.chunks(BACKWARD_CHUNK))
                    .zip(part.dn.chunks_mut(BACKWARD_CHUNK))
                {
                    self.dispatch(Backward {
                        table: &table,
                        setup: &setup,
                        px,
                        g: gp,
                        dn,
                        tex: &mut part.tex,
                        ctrl: &mut part.ctrl,
                        wanted,
                    });
                }
                part
            })
            .collect();
        // fixed-order reduction over chunks
        let mut tex = vec![0.0f64; n_tex * TEXEL_SUMS];
        let mut d_ctrl = [0.0f64; N_PARAMS];
        let mut dn = Vec::with_capacity(px.len());
        for part in parts {
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
        Gradients {
            d_env,
            d_normals,
            d_ctrl: d_ctrl.map(|x| x as f32),
        }
    }
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

impl Backend for FastCpu {
    fn describe(&self) -> String {
        let n = rayon::current_num_threads();
        format!(
            "cpu: f32 {}, {n} thread{}",
            match self.level {
                SimdLevel::Avx512 => "AVX-512",
                SimdLevel::Avx2 => "AVX2 + FMA",
                SimdLevel::Neon => "NEON",
                SimdLevel::Scalar => "scalar",
            },
            if n == 1 { "" } else { "s" }
        )
    }

    fn render_prepared(&self, preps: &[Prepared]) -> Result<Vec<Image>> {
        Ok(preps.iter().map(|p| p.image(self.forward(p))).collect())
    }

    fn backward_prepared(&self, preps: &[Prepared], upstream: &[Image]) -> Result<Vec<Gradients>> {
        self.backward_prepared_wanted(preps, upstream, Wanted::ALL)
    }

    fn backward_prepared_wanted(
        &self,
        preps: &[Prepared],
        upstream: &[Image],
        wanted: Wanted,
    ) -> Result<Vec<Gradients>> {
        Ok(preps
            .iter()
            .zip(upstream)
            .map(|(p, u)| FastCpu::backward_wanted(self, p, &u.pixels, wanted))
            .collect())
    }

    fn normal_jacobians(&self, preps: &[Prepared]) -> Result<Vec<Vec<[[f32; 3]; 3]>>> {
        Ok(preps
            .iter()
            .map(|p| FastCpu::normal_jacobians(self, p))
            .collect())
    }
}
