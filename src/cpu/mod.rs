//! The fast CPU path: the layer in f32 with explicit SIMD and rayon threads.
//!
//! One generic kernel per pass ([`forward`], [`backward`]), written on `pulp`'s `Simd`
//! trait and instantiated at run time for the widest instruction set the CPU has:
//! AVX-512 (16 lanes), AVX2 + FMA (8), NEON (4) or a scalar fallback. Texels sit in SIMD
//! lanes, tile-ordered so that a block below a pixel's horizon is skipped whole; one pixel
//! is broadcast against each block. The per-texel work of the f64 preparation is reused,
//! and the material is reduced to the lobe terms the scene needs ([`table::LobePlan`]).
//! Materials with nothing to share (every lobe its own curves: fits, networks) get
//! kernels of their own ([`dense`]), where that plan would only add bookkeeping. A
//! batch's scenes run in parallel too.
//!
//! Deterministic: pixels are cut into chunks whose number depends on the problem size
//! only, every sum runs in a fixed order, and partial sums of the backward pass are
//! added in f64 in chunk order; results are bitwise equal for any thread count.
//! Memory is O(pixels + texels x chunks).

pub mod backward;
pub mod dense;
pub mod forward;
pub mod math;
pub mod pair;
mod passes;
pub mod table;

use rayon::prelude::*;

use crate::backend::Scenes;
use crate::error::{Error, Result};
use crate::prepare::Prepared;
use crate::scene::{Gradients, Image, Wanted};
use crate::{Backend, Jacobian};

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
    /// Whether materials with nothing to share get the kernels of [`dense`].
    dense: bool,
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
        level.arch().map(|arch| FastCpu {
            level,
            arch,
            dense: true,
        })
    }

    /// The level it runs at.
    pub fn level(&self) -> SimdLevel {
        self.level
    }

    /// The same path with the general lobe-plan kernels only, also for materials with
    /// nothing to share ([`dense`]): for comparisons.
    pub fn plan_kernels_only(self) -> Self {
        FastCpu {
            dense: false,
            ..self
        }
    }

    /// f32 lanes per SIMD vector at this level.
    fn lanes(&self) -> usize {
        match self.level {
            SimdLevel::Avx512 => 16,
            SimdLevel::Avx2 => 8,
            SimdLevel::Neon => 4,
            SimdLevel::Scalar => 1,
        }
    }

    /// Runs a SIMD operation at this level.
    fn dispatch<Op: pulp::WithSimd>(&self, op: Op) -> Op::Output {
        self.arch.dispatch(op)
    }
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

    // A batch's scenes run in parallel as well as each scene's pixels: a small scene's
    // backward pass is one chunk (one thread), and a training batch is many small scenes.
    // Each scene's result does not depend on the threads.
    fn render(&self, scenes: Scenes<'_>) -> Result<Vec<Image>> {
        Ok(match scenes {
            Scenes::Batch(batch) => batch
                .scenes()
                .par_iter()
                .map(|s| {
                    let p = Prepared::new(s);
                    p.image(self.forward(&p))
                })
                .collect(),
            Scenes::Prepared(preps) => preps.par_iter().map(|p| p.image(self.forward(p))).collect(),
        })
    }

    fn backward(
        &self,
        scenes: Scenes<'_>,
        upstream: &[Image],
        wanted: Wanted,
    ) -> Result<Vec<Gradients>> {
        Ok(match scenes {
            Scenes::Batch(batch) => {
                batch.check_upstream(upstream)?;
                batch
                    .scenes()
                    .par_iter()
                    .zip(upstream)
                    .map(|(s, u)| FastCpu::backward(self, &Prepared::new(s), &u.pixels, wanted))
                    .collect()
            }
            Scenes::Prepared(preps) => preps
                .par_iter()
                .zip(upstream)
                .map(|(p, u)| FastCpu::backward(self, p, &u.pixels, wanted))
                .collect(),
        })
    }

    fn normal_jacobians(
        &self,
        preps: &[Prepared],
        backward: Option<(&[Image], Wanted)>,
    ) -> Result<Vec<(Vec<Jacobian>, Option<Gradients>)>> {
        Ok(match backward {
            None => preps
                .par_iter()
                .map(|p| FastCpu::normal_jacobians(self, p, None))
                .collect(),
            Some((upstream, wanted)) => preps
                .par_iter()
                .zip(upstream)
                .map(|(p, u)| FastCpu::normal_jacobians(self, p, Some((&u.pixels, wanted))))
                .collect(),
        })
    }
}
