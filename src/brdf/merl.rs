//! MERL measured BRDF tables (`.binary`, Matusik et al. 2003).
//!
//! A file holds three little-endian int32 dimensions (90, 90, 180 in the original
//! database: theta_h, theta_d and phi_d cells), then the red, green and blue blocks of
//! float64 values, each in the order `phi_d + theta_d * N_p + theta_h * N_p * N_d`. Stored
//! values are multiplied by 1/1500, 1.15/1500 and 1.66/1500 per channel; negative values
//! mark cells without a measurement.
//!
//! Lookups are nearest-cell, as the original reader does, with its indexing generalised
//! to the file's own dimensions (so small tables work too):
//! - theta_h: floor(sqrt(theta_h / (pi/2) * N_h * N_h)), dense near the specular peak;
//! - theta_d: floor(theta_d / (pi/2) * N_d);
//! - phi_d: folded to [0, pi) by reciprocity, floor(phi_d / pi * N_p).

use std::f64::consts::{FRAC_PI_2, PI};
use std::path::Path;

use super::Isotropic;
use crate::error::{Error, Result};

/// The per-channel scales of stored values.
pub const SCALES: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];
/// The largest dimension accepted.
const MAX_DIM: usize = 1024;

/// A measured table.
#[derive(Clone, Debug)]
pub struct Merl {
    /// The material's name (the file's stem).
    pub name: String,
    dims: [usize; 3],
    /// Scaled values, [R, G, B] per cell; negative where not measured.
    values: Vec<[f64; 3]>,
}

impl Merl {
    /// The dimensions (theta_h, theta_d, phi_d cells).
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    fn cell(&self, theta_h: f64, theta_d: f64, phi_d: f64) -> usize {
        let [nh, nd, np] = self.dims;
        let ih = if theta_h <= 0.0 {
            0
        } else {
            ((theta_h / FRAC_PI_2 * (nh * nh) as f64).sqrt() as usize).min(nh - 1)
        };
        let id = ((theta_d.max(0.0) / FRAC_PI_2 * nd as f64) as usize).min(nd - 1);
        let mut phi = phi_d.rem_euclid(2.0 * PI);
        if phi >= PI {
            phi -= PI;
        }
        let ip = ((phi / PI * np as f64) as usize).min(np - 1);
        ip + id * np + ih * np * nd
    }
}

impl Isotropic for Merl {
    fn eval(&self, theta_h: f64, theta_d: f64, phi_d: f64) -> [f64; 3] {
        self.values[self.cell(theta_h, theta_d, phi_d)].map(|v| v.max(0.0))
    }

    fn known(&self, theta_h: f64, theta_d: f64, phi_d: f64) -> bool {
        self.values[self.cell(theta_h, theta_d, phi_d)]
            .iter()
            .all(|&v| v >= 0.0)
    }
}

/// Reads a `.binary` table; the material is named after the file.
pub fn read(path: &Path) -> Result<Merl> {
    let bytes = std::fs::read(path).map_err(|e| Error::file(path, format!("cannot read: {e}")))?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    parse(&bytes, &name).map_err(|m| Error::file(path, m))
}

/// Parses the bytes of a `.binary` table; the error names the item that is wrong.
pub fn parse(bytes: &[u8], name: &str) -> std::result::Result<Merl, String> {
    if bytes.len() < 12 {
        return Err(format!(
            "MERL table: {} bytes, too short for the 12-byte header of three int32 dimensions",
            bytes.len()
        ));
    }
    let mut dims = [0usize; 3];
    for (i, d) in dims.iter_mut().enumerate() {
        let v = i32::from_le_bytes(bytes[4 * i..4 * i + 4].try_into().expect("4 bytes"));
        if v < 1 || v as usize > MAX_DIM {
            return Err(format!(
                "MERL table: dimension {} is {v}; expected 1 to {MAX_DIM} (90, 90, 180 in the database)",
                i + 1
            ));
        }
        *d = v as usize;
    }
    let cells = dims[0] * dims[1] * dims[2];
    let data = &bytes[12..];
    if data.len() != 3 * 8 * cells {
        return Err(format!(
            "MERL table: header says {} x {} x {} ({} bytes of data) but the file has {} bytes after the header",
            dims[0],
            dims[1],
            dims[2],
            3 * 8 * cells,
            data.len()
        ));
    }
    let mut values = vec![[0.0; 3]; cells];
    for (k, block) in data.chunks_exact(8 * cells).enumerate() {
        for (i, raw) in block.chunks_exact(8).enumerate() {
            let v = f64::from_le_bytes(raw.try_into().expect("8 bytes"));
            if !v.is_finite() {
                return Err(format!(
                    "MERL table: value {i} of the {} block is {v}",
                    ["red", "green", "blue"][k]
                ));
            }
            values[i][k] = if v < 0.0 { -1.0 } else { v * SCALES[k] };
        }
    }
    Ok(Merl {
        name: name.to_string(),
        dims,
        values,
    })
}

/// The Rusinkiewicz angles at the centre of cell (ih, id, ip) of a table of `dims`:
/// lookups anywhere inside the cell return it.
pub fn cell_centre(dims: [usize; 3], ih: usize, id: usize, ip: usize) -> [f64; 3] {
    let [nh, nd, np] = dims;
    let u = (ih as f64 + 0.5) / nh as f64;
    [
        u * u * FRAC_PI_2,
        (id as f64 + 0.5) / nd as f64 * FRAC_PI_2,
        (ip as f64 + 0.5) / np as f64 * PI,
    ]
}

/// The bytes of a `.binary` table of `dims` holding `brdf` at the cells' centres.
pub fn encode(dims: [usize; 3], brdf: &dyn Isotropic) -> Vec<u8> {
    let [nh, nd, np] = dims;
    let cells = nh * nd * np;
    let mut values = vec![[0.0; 3]; cells];
    for ih in 0..nh {
        for id in 0..nd {
            for ip in 0..np {
                let [th, td, pd] = cell_centre(dims, ih, id, ip);
                values[ip + id * np + ih * np * nd] = brdf.eval(th, td, pd);
            }
        }
    }
    let mut out = Vec::with_capacity(12 + 24 * cells);
    for d in dims {
        out.extend_from_slice(&(d as i32).to_le_bytes());
    }
    for k in 0..3 {
        for v in &values {
            out.extend_from_slice(&(v[k] / SCALES[k]).to_le_bytes());
        }
    }
    out
}

/// Writes `brdf` as a `.binary` table of `dims` (cells' centres, see [`cell_centre`]).
pub fn write(path: &Path, dims: [usize; 3], brdf: &dyn Isotropic) -> Result<()> {
    if dims.iter().any(|d| !(1..=MAX_DIM).contains(d)) {
        return Err(Error::file(
            path,
            format!("MERL table: dimensions {dims:?} must each be 1 to {MAX_DIM}"),
        ));
    }
    crate::io::write_atomic(path, &encode(dims, brdf))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_and_scales() {
        // 2 x 1 x 2 cells: values 1..4 per block, the blue block's last one missing.
        let mut bytes = Vec::new();
        for d in [2i32, 1, 2] {
            bytes.extend_from_slice(&d.to_le_bytes());
        }
        for k in 0..3 {
            for i in 0..4 {
                let v = if k == 2 && i == 3 {
                    -1.0
                } else {
                    (i + 1) as f64
                };
                bytes.extend_from_slice(&(v * 1500.0).to_le_bytes());
            }
        }
        let m = parse(&bytes, "t").unwrap();
        // theta_h cell 1, phi_d cell 1 = index 3.
        let v = m.eval(1.2, 0.3, 2.0);
        assert_eq!(v, [4.0, 4.0 * 1.15, 0.0]);
        assert!(!m.known(1.2, 0.3, 2.0));
        // phi_d folds: pi + 0.1 is cell 0.
        assert_eq!(m.eval(1.2, 0.3, PI + 0.1)[0], 3.0);
        assert!(m.known(0.0, 0.0, 0.0));
        assert_eq!(m.eval(0.0, 0.0, 0.0)[1], 1.15);
    }

    #[test]
    fn bad_tables_name_the_item() {
        assert!(parse(&[0; 5], "t").unwrap_err().contains("too short"));
        let mut bytes = Vec::new();
        for d in [2i32, 0, 2] {
            bytes.extend_from_slice(&d.to_le_bytes());
        }
        assert!(parse(&bytes, "t").unwrap_err().contains("dimension 2 is 0"));
        let mut bytes = Vec::new();
        for d in [1i32, 1, 1] {
            bytes.extend_from_slice(&d.to_le_bytes());
        }
        bytes.extend_from_slice(&[0; 16]);
        assert!(
            parse(&bytes, "t")
                .unwrap_err()
                .contains("16 bytes after the header")
        );
        bytes.extend_from_slice(&f64::NAN.to_le_bytes());
        assert!(
            parse(&bytes, "t")
                .unwrap_err()
                .contains("blue block is NaN")
        );
    }

    struct Analytic;
    impl Isotropic for Analytic {
        fn eval(&self, th: f64, td: f64, pd: f64) -> [f64; 3] {
            let v = 0.2 + 3.0 * th.cos().powf(40.0) * (1.0 + td.sin()) * (1.0 + 0.1 * pd.cos());
            [v, 0.5 * v, 0.25 * v]
        }
    }

    #[test]
    fn round_trip_through_cells() {
        let dims = [16, 8, 12];
        let bytes = encode(dims, &Analytic);
        assert_eq!(bytes.len(), 12 + 3 * 8 * 16 * 8 * 12);
        let m = parse(&bytes, "a").unwrap();
        for ih in 0..16 {
            for id in 0..8 {
                for ip in 0..12 {
                    let [th, td, pd] = cell_centre(dims, ih, id, ip);
                    let want = Analytic.eval(th, td, pd);
                    let got = m.eval(th, td, pd);
                    for k in 0..3 {
                        assert!(
                            (got[k] - want[k]).abs() <= 1e-12 * want[k],
                            "{ih} {id} {ip}"
                        );
                    }
                    // Anywhere in the cell (theta_h cells are uniform in sqrt(theta_h)),
                    // and across phi_d's fold.
                    for f in [0.25, 0.75] {
                        let u = (ih as f64 + f) / 16.0;
                        assert_eq!(m.eval(u * u * FRAC_PI_2, td, pd + PI), got);
                    }
                }
            }
        }
    }
}
