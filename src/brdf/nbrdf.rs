//! Neural BRDFs: one small network per material (6-21-21-3, ReLU, output exp(y) - 1),
//! the compact form of the MERL database that `data/merl/merl_nbrdf.json` holds.
//!
//! A file is `{"format": "nbrdf-6-21-21-3", "materials": {NAME: {"w1", "b1", "w2", "b2",
//! "w3", "b3"}}}` with w1 6 x 21, w2 21 x 21, w3 21 x 3 (rows are inputs). Material M at
//! (theta_h, theta_d, phi_d):
//!
//! ```text
//! x  = [sin th, 0, cos th, sin td cos pd, sin td sin pd, cos td]
//! a1 = relu(x w1 + b1),  a2 = relu(a1 w2 + b2),  f = max(exp(a2 w3 + b3) - 1, 0)
//! ```

use std::path::Path;

use serde_json::Value;

use super::Isotropic;
use crate::error::{Error, Result};

const IN: usize = 6;
const HIDDEN: usize = 21;
const OUT: usize = 3;
/// The one format this reader knows.
pub const FORMAT: &str = "nbrdf-6-21-21-3";

/// One material's network.
#[derive(Clone, Debug)]
pub struct Nbrdf {
    /// The material's name in its file.
    pub name: String,
    w1: [[f64; HIDDEN]; IN],
    b1: [f64; HIDDEN],
    w2: [[f64; HIDDEN]; HIDDEN],
    b2: [f64; HIDDEN],
    w3: [[f64; OUT]; HIDDEN],
    b3: [f64; OUT],
}

impl Nbrdf {
    /// The network's RGB value for the input vector `x`.
    fn forward(&self, x: [f64; IN]) -> [f64; 3] {
        let mut a1 = self.b1;
        for (xi, row) in x.iter().zip(&self.w1) {
            for (a, w) in a1.iter_mut().zip(row) {
                *a += xi * w;
            }
        }
        let mut a2 = self.b2;
        for (ai, row) in a1.iter().zip(&self.w2) {
            let ai = ai.max(0.0);
            for (a, w) in a2.iter_mut().zip(row) {
                *a += ai * w;
            }
        }
        let mut y = self.b3;
        for (ai, row) in a2.iter().zip(&self.w3) {
            let ai = ai.max(0.0);
            for (o, w) in y.iter_mut().zip(row) {
                *o += ai * w;
            }
        }
        y.map(|v| v.exp_m1().max(0.0))
    }
}

impl Isotropic for Nbrdf {
    fn eval(&self, theta_h: f64, theta_d: f64, phi_d: f64) -> [f64; 3] {
        let (sh, ch) = theta_h.sin_cos();
        let (sd, cd) = theta_d.sin_cos();
        let (sp, cp) = phi_d.sin_cos();
        self.forward([sh, 0.0, ch, sd * cp, sd * sp, cd])
    }
}

/// Reads every material of an NBRDF file, in the file's name order.
pub fn read(path: &Path) -> Result<Vec<Nbrdf>> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| Error::file(path, format!("cannot read: {e}")))?;
    parse(&text).map_err(|m| Error::file(path, m))
}

/// Parses the text of an NBRDF file; the error says which item is wrong.
pub fn parse(text: &str) -> std::result::Result<Vec<Nbrdf>, String> {
    let root: Value = serde_json::from_str(text).map_err(|e| format!("not JSON: {e}"))?;
    match root.get("format").and_then(Value::as_str) {
        Some(FORMAT) => {}
        Some(other) => return Err(format!("format is '{other}'; only '{FORMAT}' is known")),
        None => return Err(format!("no \"format\": \"{FORMAT}\" entry")),
    }
    let materials = root
        .get("materials")
        .and_then(Value::as_object)
        .ok_or("no \"materials\" object")?;
    if materials.is_empty() {
        return Err("\"materials\" is empty".into());
    }
    let mut out: Vec<Nbrdf> = materials
        .iter()
        .map(|(name, m)| network(name, m))
        .collect::<std::result::Result<_, _>>()?;
    out.sort_by(|a, b| a.name.cmp(&b.name));
    Ok(out)
}

fn network(name: &str, m: &Value) -> std::result::Result<Nbrdf, String> {
    let vector = |key: &str, len: usize| -> std::result::Result<Vec<f64>, String> {
        let v = m
            .get(key)
            .and_then(Value::as_array)
            .ok_or_else(|| format!("material '{name}': no array \"{key}\""))?;
        if v.len() != len {
            return Err(format!(
                "material '{name}': \"{key}\" has {} entries, expected {len}",
                v.len()
            ));
        }
        v.iter()
            .enumerate()
            .map(|(i, x)| match x.as_f64() {
                Some(x) if x.is_finite() => Ok(x),
                _ => Err(format!(
                    "material '{name}': \"{key}\"[{i}] is not a finite number"
                )),
            })
            .collect()
    };
    let matrix = |key: &str, rows: usize, cols: usize| -> std::result::Result<Vec<f64>, String> {
        let v = m
            .get(key)
            .and_then(Value::as_array)
            .ok_or_else(|| format!("material '{name}': no array \"{key}\""))?;
        if v.len() != rows {
            return Err(format!(
                "material '{name}': \"{key}\" has {} rows, expected {rows}",
                v.len()
            ));
        }
        let mut out = Vec::with_capacity(rows * cols);
        for (r, row) in v.iter().enumerate() {
            let row = row
                .as_array()
                .filter(|row| row.len() == cols)
                .ok_or_else(|| {
                    format!("material '{name}': \"{key}\"[{r}] is not a row of {cols} numbers")
                })?;
            for (c, x) in row.iter().enumerate() {
                match x.as_f64() {
                    Some(x) if x.is_finite() => out.push(x),
                    _ => {
                        return Err(format!(
                            "material '{name}': \"{key}\"[{r}][{c}] is not a finite number"
                        ));
                    }
                }
            }
        }
        Ok(out)
    };
    fn rows<const C: usize>(flat: &[f64]) -> impl Iterator<Item = [f64; C]> + '_ {
        flat.chunks_exact(C)
            .map(|c| c.try_into().expect("chunk of C"))
    }
    let w1 = matrix("w1", IN, HIDDEN)?;
    let w2 = matrix("w2", HIDDEN, HIDDEN)?;
    let w3 = matrix("w3", HIDDEN, OUT)?;
    let mut net = Nbrdf {
        name: name.to_string(),
        w1: [[0.0; HIDDEN]; IN],
        b1: vector("b1", HIDDEN)?.try_into().expect("length checked"),
        w2: [[0.0; HIDDEN]; HIDDEN],
        b2: vector("b2", HIDDEN)?.try_into().expect("length checked"),
        w3: [[0.0; OUT]; HIDDEN],
        b3: vector("b3", OUT)?.try_into().expect("length checked"),
    };
    for (dst, src) in net.w1.iter_mut().zip(rows::<HIDDEN>(&w1)) {
        *dst = src;
    }
    for (dst, src) in net.w2.iter_mut().zip(rows::<HIDDEN>(&w2)) {
        *dst = src;
    }
    for (dst, src) in net.w3.iter_mut().zip(rows::<OUT>(&w3)) {
        *dst = src;
    }
    Ok(net)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A network whose only path is input 2 (cos theta_h) -> hidden 0 -> hidden 0 -> all
    /// outputs: f = exp(cos theta_h) - 1.
    fn tiny() -> String {
        let zeros = |r: usize, c: usize| vec![vec![0.0; c]; r];
        let mut w1 = zeros(IN, HIDDEN);
        w1[2][0] = 1.0;
        let mut w2 = zeros(HIDDEN, HIDDEN);
        w2[0][0] = 1.0;
        let mut w3 = zeros(HIDDEN, OUT);
        w3[0] = vec![1.0, 1.0, 1.0];
        serde_json::json!({
            "format": FORMAT,
            "materials": {"b": {"w1": w1, "b1": vec![0.0; HIDDEN], "w2": w2,
                "b2": vec![0.0; HIDDEN], "w3": w3, "b3": vec![0.0; OUT]},
                "a": {"w1": zeros(IN, HIDDEN), "b1": vec![0.0; HIDDEN], "w2": zeros(HIDDEN, HIDDEN),
                "b2": vec![0.0; HIDDEN], "w3": zeros(HIDDEN, OUT), "b3": vec![0.5; OUT]}}
        })
        .to_string()
    }

    #[test]
    fn evaluates_the_documented_network() {
        let nets = parse(&tiny()).unwrap();
        assert_eq!(nets[0].name, "a");
        assert_eq!(nets[1].name, "b");
        let f = nets[1].eval(0.3, 0.2, 1.0);
        assert!((f[0] - 0.3f64.cos().exp_m1()).abs() < 1e-12);
        assert!((nets[0].eval(0.3, 0.2, 1.0)[2] - 0.5f64.exp_m1()).abs() < 1e-12);
    }

    #[test]
    fn names_the_bad_item() {
        let bad = tiny().replacen("\"b3\":[0.0,0.0,0.0]", "\"b3\":[0.0,0.0]", 1);
        let e = parse(&bad).unwrap_err();
        assert!(e.contains("material 'b'") && e.contains("\"b3\""), "{e}");
        let e = parse("{\"format\": \"x\"}").unwrap_err();
        assert!(e.contains("format is 'x'"), "{e}");
    }
}
