//! The one kind of array the nets pass between layers: `c` planes of H x W float32 values,
//! one image (model.py's (1, C, H, W) tensors), and the matrix product they are built on.

use rayon::prelude::*;

/// `c` channels of an H x W image, channel-major: value (ci, y, x) at (ci h + y) w + x.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Planes {
    pub(super) c: usize,
    pub(super) h: usize,
    pub(super) w: usize,
    pub(super) v: Vec<f32>,
}

impl Planes {
    pub(super) fn new(c: usize, h: usize, w: usize, v: Vec<f32>) -> Planes {
        assert_eq!(v.len(), c * h * w, "planes: {c} x {h} x {w} values");
        Planes { c, h, w, v }
    }

    /// Pixels per channel.
    pub(super) fn area(&self) -> usize {
        self.h * self.w
    }

    /// Channel `ci`'s H x W values.
    pub(super) fn plane(&self, ci: usize) -> &[f32] {
        &self.v[ci * self.area()..(ci + 1) * self.area()]
    }

    /// Every plane mirrored left to right (torch.flip along the last dimension).
    pub(super) fn mirrored(&self) -> Planes {
        let v = self
            .v
            .chunks_exact(self.w)
            .flat_map(|row| row.iter().rev().copied())
            .collect();
        Planes::new(self.c, self.h, self.w, v)
    }

    /// `self`'s channels, then `other`'s (torch.cat along dimension 1).
    pub(super) fn cat(&self, other: &Planes) -> Planes {
        assert_eq!((self.h, self.w), (other.h, other.w), "cat: sizes differ");
        let mut v = Vec::with_capacity(self.v.len() + other.v.len());
        v.extend_from_slice(&self.v);
        v.extend_from_slice(&other.v);
        Planes::new(self.c + other.c, self.h, self.w, v)
    }

    /// 2 x 2 max pooling, stride 2 (F.max_pool2d(x, 2): odd last rows and columns dropped).
    pub(super) fn max_pool2(&self) -> Planes {
        let (h, w) = (self.h / 2, self.w / 2);
        let mut v = Vec::with_capacity(self.c * h * w);
        for ci in 0..self.c {
            let p = self.plane(ci);
            for y in 0..h {
                let (r0, r1) = (&p[2 * y * self.w..], &p[(2 * y + 1) * self.w..]);
                v.extend((0..w).map(|x| {
                    r0[2 * x]
                        .max(r0[2 * x + 1])
                        .max(r1[2 * x].max(r1[2 * x + 1]))
                }));
            }
        }
        Planes::new(self.c, h, w, v)
    }

    /// f x f average pooling, stride f (H and W multiples of f).
    pub(super) fn avg_pool(&self, f: usize) -> Planes {
        let (h, w) = (self.h / f, self.w / f);
        let mut v = vec![0f32; self.c * h * w];
        for ci in 0..self.c {
            let p = self.plane(ci);
            let out = &mut v[ci * h * w..(ci + 1) * h * w];
            for y in 0..h * f {
                for x in 0..w * f {
                    out[y / f * w + x / f] += p[y * self.w + x];
                }
            }
        }
        let n = (f * f) as f32;
        v.iter_mut().for_each(|v| *v /= n);
        Planes::new(self.c, h, w, v)
    }
}

/// C = A B for row-major A (m x k) and B (k x n), or A given transposed (`a_t`: A's
/// values are stored k x m), into C (m x n, row-major). matrixmultiply's kernels, with the
/// columns split over rayon's threads when there are enough of them.
pub(super) fn matmul(a: &[f32], a_t: bool, b: &[f32], m: usize, k: usize, n: usize) -> Vec<f32> {
    assert!(
        a.len() == m * k && b.len() == k * n,
        "matmul: {m} x {k} x {n}"
    );
    let mut c = vec![0f32; m * n];
    if m == 0 || n == 0 {
        return c;
    }
    let (rsa, csa) = if a_t {
        (1, m as isize)
    } else {
        (k as isize, 1)
    };
    // blocks of columns: each a product of A with B's columns j0..j1 into C's
    const BLOCK: usize = 1024;
    let blocks: Vec<(usize, usize)> = (0..n)
        .step_by(BLOCK)
        .map(|j0| (j0, (j0 + BLOCK).min(n)))
        .collect();
    let c_ptr = SendPtr(c.as_mut_ptr());
    blocks.par_iter().for_each(|&(j0, j1)| {
        let c_ptr = &c_ptr;
        // SAFETY: A is m x k and B k x n by the assertion above, with the strides given;
        // the blocks' columns j0..j1 of C are disjoint, so no two threads write one value,
        // and `c` outlives the parallel loop.
        unsafe {
            matrixmultiply::sgemm(
                m,
                k,
                j1 - j0,
                1.0,
                a.as_ptr(),
                rsa,
                csa,
                b.as_ptr().add(j0),
                n as isize,
                1,
                0.0,
                c_ptr.0.add(j0),
                n as isize,
                1,
            );
        }
    });
    c
}

/// C's pointer, shared by the threads that write its disjoint column blocks.
struct SendPtr(*mut f32);
// SAFETY: only used by `matmul`, whose threads write disjoint parts of one live buffer.
unsafe impl Sync for SendPtr {}

#[cfg(test)]
mod tests {
    use super::*;

    /// The product against a direct triple loop, plain and transposed, on sizes that do
    /// and do not fill a column block.
    #[test]
    fn matmul_matches_a_direct_loop() {
        for (m, k, n) in [(3, 5, 7), (8, 27, 1030), (1, 1, 1), (4, 0, 3)] {
            let a: Vec<f32> = (0..m * k).map(|i| ((i * 7 % 11) as f32) - 5.0).collect();
            let b: Vec<f32> = (0..k * n).map(|i| ((i * 5 % 13) as f32) * 0.25).collect();
            let want: Vec<f32> = (0..m * n)
                .map(|ij| (0..k).map(|l| a[ij / n * k + l] * b[l * n + ij % n]).sum())
                .collect();
            assert_eq!(matmul(&a, false, &b, m, k, n), want);
            let a_t: Vec<f32> = (0..k * m).map(|i| a[i % m * k + i / m]).collect();
            assert_eq!(matmul(&a_t, true, &b, m, k, n), want);
        }
    }

    #[test]
    fn pooling_and_cat() {
        let p = Planes::new(1, 2, 4, vec![1., 2., 3., 4., 5., 6., 7., 9.]);
        assert_eq!(p.max_pool2().v, vec![6., 9.]);
        assert_eq!(p.avg_pool(2).v, vec![3.5, 5.75]);
        let q = p.cat(&p);
        assert_eq!((q.c, q.plane(1)), (2, p.plane(0)));
    }
}
