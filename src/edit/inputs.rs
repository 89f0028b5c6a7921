//! What a fit is fitted to: the object's normals, the image and the pixels that count,
//! loaded from files and checked against each other, and box-filtered to the working size.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result, invalid};
use crate::io;
use crate::raster;
use crate::scene::{Image, NormalMap};

/// Where the object's normals come from.
#[derive(Clone, Debug, PartialEq)]
pub enum ObjectNormals {
    /// A normal-map file of the image's size.
    File(PathBuf),
    /// A unit sphere filling the (square) image, which must be `N` x `N` if given.
    Sphere(Option<usize>),
}

/// What is fitted to: normals, the image, and which pixels count.
#[derive(Clone, Debug)]
pub struct Inputs {
    /// The object's normals (background pixels never count).
    pub normals: NormalMap,
    /// The image, linear RGB.
    pub target: Image,
    /// Pixels that count: inside the mask and not background.
    pub mask: Vec<bool>,
}

impl Inputs {
    /// Inputs of one size; `mask` (true = counts) defaults to every non-background pixel.
    pub fn new(normals: NormalMap, target: Image, mask: Option<Vec<bool>>) -> Result<Self> {
        normals.validate()?;
        if (target.width, target.height) != (normals.width, normals.height) {
            return Err(invalid!(
                "image: size {}x{} differs from the normals' {}x{}",
                target.width,
                target.height,
                normals.width,
                normals.height
            ));
        }
        if let Some((x, y)) = target.non_finite_pixel() {
            return Err(invalid!("image: pixel (column {x}, row {y}) is not finite"));
        }
        let n = normals.normals.len();
        let given = mask.unwrap_or_else(|| vec![true; n]);
        if given.len() != n {
            return Err(invalid!(
                "mask: {} pixels for a {}x{} image",
                given.len(),
                target.width,
                target.height
            ));
        }
        let mask: Vec<bool> = (0..n)
            .map(|i| given[i] && !normals.is_background(i))
            .collect();
        if !mask.iter().any(|&m| m) {
            return Err(invalid!(
                "mask: no pixel is both in the mask and on the object"
            ));
        }
        Ok(Inputs {
            normals,
            target,
            mask,
        })
    }

    /// Inputs from files: the image at `image` (.exr, .npy or .png), the normals `shape`
    /// says, and `mask` (.png, .exr or .npy; first channel above half) if given. Sizes
    /// must agree; errors name the file at fault.
    pub fn load(image: &Path, shape: &ObjectNormals, mask: Option<&Path>) -> Result<Self> {
        let target = io::load_image(image)?;
        let normals = match shape {
            ObjectNormals::File(p) => io::load_normals(p)?,
            ObjectNormals::Sphere(n) => {
                if target.width != target.height || n.is_some_and(|n| n != target.width) {
                    return Err(Error::file(
                        image,
                        format!(
                            "size {}x{} is not the {}sphere's",
                            target.width,
                            target.height,
                            n.map_or(String::new(), |n| format!("{n}x{n} "))
                        ),
                    ));
                }
                NormalMap::sphere(target.width)
            }
        };
        if (normals.width, normals.height) != (target.width, target.height) {
            return Err(Error::file(
                image,
                format!(
                    "size {}x{} differs from the normals' {}x{}",
                    target.width, target.height, normals.width, normals.height
                ),
            ));
        }
        let mask = match mask {
            None => None,
            Some(p) => {
                let (w, h, m) = io::load_mask(p)?;
                if (w, h) != (target.width, target.height) {
                    return Err(Error::file(
                        p,
                        format!(
                            "size {w}x{h} differs from the image's {}x{}",
                            target.width, target.height
                        ),
                    ));
                }
                Some(m)
            }
        };
        Inputs::new(normals, target, mask).map_err(|e| match e {
            Error::Invalid(m) => Error::file(image, m),
            other => other,
        })
    }

    /// Box-filtered by a whole factor to at most `work_size` pixels on the longer side (0:
    /// full size), as the fit runs on it.
    pub fn at_work_size(&self, work_size: usize) -> Inputs {
        let side = self.target.width.max(self.target.height);
        let factor = if work_size == 0 {
            1
        } else {
            side.div_ceil(work_size).max(1)
        };
        self.downsampled(factor)
    }

    /// Box-filtered by `factor` per axis (the size rounded down): normals averaged and
    /// normalised, the image averaged, a pixel kept in the mask when all of its block is.
    pub fn downsampled(&self, factor: usize) -> Inputs {
        if factor <= 1 {
            return self.clone();
        }
        let (w, h) = (self.target.width / factor, self.target.height / factor);
        let (w, h) = (w.max(1), h.max(1));
        let reduced = raster::reduce(
            (self.target.width, self.target.height),
            (factor, factor),
            (w, h),
            |block| {
                let (mut n, mut p, mut all) = ([0.0f64; 3], [0.0f64; 3], true);
                let mut count = 0.0;
                for i in block {
                    for k in 0..3 {
                        n[k] += f64::from(self.normals.normals[i][k]);
                        p[k] += f64::from(self.target.pixels[i][k]);
                    }
                    all &= self.mask[i];
                    count += 1.0;
                }
                let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                let keep = all && len > 1e-6;
                let normal = if keep {
                    n.map(|v| (v / len) as f32)
                } else {
                    [0.0; 3]
                };
                (normal, p.map(|v| (v / count) as f32), keep)
            },
        );
        let normals = reduced.iter().map(|r| r.0).collect();
        let pixels = reduced.iter().map(|r| r.1).collect();
        let mask = reduced.iter().map(|r| r.2).collect();
        Inputs {
            normals: NormalMap {
                width: w,
                height: h,
                normals,
            },
            target: Image {
                width: w,
                height: h,
                pixels,
            },
            mask,
        }
    }
}
