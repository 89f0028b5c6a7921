//! NumPy `.npy` arrays: a reader for float32/float64 arrays of any shape (format versions
//! 1, 2 and 3, either byte order, C or Fortran order) and a writer for float32 C-order
//! arrays (version 1).
//!
//! The format is a magic string, a version, a header length, a Python-literal header
//! dictionary (`descr`, `fortran_order`, `shape`) padded to a multiple of 64 bytes, then
//! the raw data.

use std::path::Path;

use crate::error::{Error, Result};

const MAGIC: &[u8] = b"\x93NUMPY";

/// Most axes a shape may have (NumPy's own limit is 32, 64 since NumPy 2): reordering a
/// Fortran-order array costs a pass over the axes per element.
const MAX_DIMS: usize = 64;

/// The element types the reader understands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dtype {
    /// 32-bit IEEE float.
    F32,
    /// 64-bit IEEE float.
    F64,
}

impl Dtype {
    fn size(self) -> usize {
        match self {
            Dtype::F32 => 4,
            Dtype::F64 => 8,
        }
    }

    /// The NumPy name, e.g. `float32`.
    pub fn name(self) -> &'static str {
        match self {
            Dtype::F32 => "float32",
            Dtype::F64 => "float64",
        }
    }
}

/// An array read from a `.npy` file, its data in C (row-major) order whatever the file's.
#[derive(Clone, Debug, PartialEq)]
pub struct NpyArray {
    /// The element type in the file.
    pub dtype: Dtype,
    /// The shape, outermost axis first.
    pub shape: Vec<usize>,
    /// The elements in C order, widened to f64.
    pub data: Vec<f64>,
}

/// The parsed header of a `.npy` file.
struct Header {
    dtype: Dtype,
    big_endian: bool,
    fortran_order: bool,
    shape: Vec<usize>,
    data_offset: usize,
}

/// Reads a `.npy` file.
pub fn read(path: &Path) -> Result<NpyArray> {
    let bytes = super::read_bytes(path)?;
    parse(&bytes).map_err(|m| Error::file(path, m))
}

/// Parses the bytes of a `.npy` file; the error is a message without the file name.
pub fn parse(bytes: &[u8]) -> std::result::Result<NpyArray, String> {
    let h = parse_header(bytes)?;
    let count = h
        .shape
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .ok_or_else(|| format!("shape {:?} is too large", h.shape))?;
    let need = count
        .checked_mul(h.dtype.size())
        .ok_or_else(|| format!("shape {:?} is too large", h.shape))?;
    let body = &bytes[h.data_offset..];
    if body.len() < need {
        return Err(format!(
            "truncated: shape {} of {} needs {need} bytes of data, the file has {}",
            shape_str(&h.shape),
            h.dtype.name(),
            body.len()
        ));
    }
    let body = &body[..need];
    let raw: Vec<f64> = match (h.dtype, h.big_endian) {
        (Dtype::F32, false) => body
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64)
            .collect(),
        (Dtype::F32, true) => body
            .chunks_exact(4)
            .map(|c| f32::from_be_bytes([c[0], c[1], c[2], c[3]]) as f64)
            .collect(),
        (Dtype::F64, false) => body
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
            .collect(),
        (Dtype::F64, true) => body
            .chunks_exact(8)
            .map(|c| f64::from_be_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
            .collect(),
    };
    let data = if h.fortran_order && h.shape.len() > 1 {
        fortran_to_c(&raw, &h.shape)
    } else {
        raw
    };
    Ok(NpyArray {
        dtype: h.dtype,
        shape: h.shape,
        data,
    })
}

/// Reorders a Fortran-order (first axis fastest) array into C order (last axis fastest).
fn fortran_to_c(raw: &[f64], shape: &[usize]) -> Vec<f64> {
    let mut out = vec![0.0; raw.len()];
    let mut idx = vec![0usize; shape.len()];
    for v in out.iter_mut() {
        // Fortran offset of the C-order multi-index `idx`.
        let mut off = 0;
        for a in (0..shape.len()).rev() {
            off = off * shape[a] + idx[a];
        }
        *v = raw[off];
        // advance idx in C order
        for a in (0..shape.len()).rev() {
            idx[a] += 1;
            if idx[a] < shape[a] {
                break;
            }
            idx[a] = 0;
        }
    }
    out
}

fn parse_header(bytes: &[u8]) -> std::result::Result<Header, String> {
    if bytes.len() < 10 || &bytes[..6] != MAGIC {
        return Err("not a NumPy .npy file (no \\x93NUMPY magic)".into());
    }
    let major = bytes[6];
    let (len, start) = match major {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10usize),
        2 | 3 => {
            if bytes.len() < 12 {
                return Err("truncated header".into());
            }
            (
                u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
                12,
            )
        }
        v => {
            return Err(format!(
                "NPY format version {v} is not supported (1, 2 or 3)"
            ));
        }
    };
    let end = start
        .checked_add(len)
        .filter(|&e| e <= bytes.len())
        .ok_or("truncated header")?;
    let text =
        std::str::from_utf8(&bytes[start..end]).map_err(|_| "header is not text".to_string())?;

    let descr = dict_value(text, "descr").ok_or("header has no 'descr'")?;
    let descr = descr.trim_matches(|c| c == '\'' || c == '"');
    let (big_endian, dtype) = match descr {
        "<f4" | "=f4" => (false, Dtype::F32),
        ">f4" => (true, Dtype::F32),
        "<f8" | "=f8" => (false, Dtype::F64),
        ">f8" => (true, Dtype::F64),
        other => {
            return Err(format!(
                "dtype '{other}' is not supported; save the array as float32 ('<f4') or float64 ('<f8')"
            ));
        }
    };
    let fortran_order = match dict_value(text, "fortran_order") {
        Some("True") => true,
        Some("False") | None => false,
        Some(v) => return Err(format!("header 'fortran_order' is {v}")),
    };
    let shape_text = dict_value(text, "shape").ok_or("header has no 'shape'")?;
    let inner = shape_text
        .strip_prefix('(')
        .and_then(|s| s.strip_suffix(')'))
        .ok_or_else(|| format!("header 'shape' {shape_text} is not a tuple"))?;
    let shape = inner
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.trim_end_matches('L')
                .parse::<usize>()
                .map_err(|_| format!("header 'shape' {shape_text} is not a tuple of sizes"))
        })
        .collect::<std::result::Result<Vec<_>, _>>()?;
    if shape.len() > MAX_DIMS {
        return Err(format!(
            "header 'shape' has {} axes; NumPy writes at most {MAX_DIMS}",
            shape.len()
        ));
    }
    Ok(Header {
        dtype,
        big_endian,
        fortran_order,
        shape,
        data_offset: end,
    })
}

/// The text of the value of `key` in a Python dict literal, for the three keys a `.npy`
/// header has: a quoted string, True/False, or a parenthesised tuple.
fn dict_value<'a>(text: &'a str, key: &str) -> Option<&'a str> {
    let pos = text
        .find(&format!("'{key}'"))
        .or_else(|| text.find(&format!("\"{key}\"")))?;
    let rest = &text[pos + key.len() + 2..];
    let rest = rest.trim_start().strip_prefix(':')?.trim_start();
    let end = if rest.starts_with('(') {
        rest.find(')')? + 1
    } else if let Some(q) = rest.chars().next().filter(|&c| c == '\'' || c == '"') {
        rest[1..].find(q)? + 2
    } else {
        rest.find([',', '}']).unwrap_or(rest.len())
    };
    Some(rest[..end].trim())
}

/// `(2, 3, 3)` for a shape.
pub fn shape_str(shape: &[usize]) -> String {
    match shape {
        [one] => format!("({one},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// Encodes a float32 C-order array of the given shape as a version-1 `.npy` file.
///
/// `data.len()` must equal the product of `shape`.
pub fn encode_f32(shape: &[usize], data: &[f32]) -> Vec<u8> {
    debug_assert_eq!(shape.iter().product::<usize>(), data.len());
    let mut header = format!(
        "{{'descr': '<f4', 'fortran_order': False, 'shape': {}, }}",
        shape_str(shape)
    );
    // Pad with spaces so that magic + version + length + header + '\n' is a multiple of 64.
    let unpadded = MAGIC.len() + 2 + 2 + header.len() + 1;
    header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + data.len() * 4);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&[1, 0]);
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// Encodes an H x W x 3 float32 image.
pub fn encode_rgb(width: usize, height: usize, pixels: &[[f32; 3]]) -> Vec<u8> {
    encode_f32(&[height, width, 3], pixels.as_flattened())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_alignment() {
        let data: Vec<f32> = (0..24).map(|i| i as f32 * 0.5 - 3.0).collect();
        let bytes = encode_f32(&[2, 4, 3], &data);
        let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        assert_eq!((10 + header_len) % 64, 0);
        let a = parse(&bytes).unwrap();
        assert_eq!(a.shape, vec![2, 4, 3]);
        assert_eq!(a.dtype, Dtype::F32);
        assert_eq!(a.data, data.iter().map(|&v| v as f64).collect::<Vec<_>>());
    }

    #[test]
    fn fortran_order_and_f64_big_endian() {
        // shape (2, 3): C order [[0, 1, 2], [3, 4, 5]]; Fortran stores 0, 3, 1, 4, 2, 5.
        let header = "{'descr': '>f8', 'fortran_order': True, 'shape': (2, 3), }";
        let mut bytes = MAGIC.to_vec();
        bytes.extend_from_slice(&[2, 0]);
        bytes.extend_from_slice(&(header.len() as u32).to_le_bytes());
        bytes.extend_from_slice(header.as_bytes());
        for v in [0.0f64, 3.0, 1.0, 4.0, 2.0, 5.0] {
            bytes.extend_from_slice(&v.to_be_bytes());
        }
        let a = parse(&bytes).unwrap();
        assert_eq!(a.shape, vec![2, 3]);
        assert_eq!(a.data, vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
    }

    #[test]
    fn errors() {
        assert!(parse(b"hello").unwrap_err().contains("magic"));
        let mut bytes = encode_f32(&[2, 2, 3], &[0.0; 12]);
        bytes.truncate(bytes.len() - 4);
        assert!(parse(&bytes).unwrap_err().contains("truncated"));
        let mut bytes = encode_f32(&[1], &[0.0]);
        let p = bytes.windows(3).position(|w| w == b"<f4").unwrap();
        bytes[p + 1] = b'i';
        assert!(parse(&bytes).unwrap_err().contains("'<i4'"));
    }
}
