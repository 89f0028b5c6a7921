//! Values and corruptions: the values validators exist for, and changes to valid files
//! (truncations, byte flips, header fields patched in place).

use proptest::prelude::*;
use proptest::sample::{Index, select};

/// Ordinary values, and the ones validators exist for: NaN, infinities, negatives, huge
/// and tiny values, the limits and just past them.
const SPECIAL: &[f64] = &[
    0.0,
    -0.0,
    1.0,
    -1.0,
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    40.0,
    -40.0,
    40.000_001,
    1.0e4,
    10_000.000_1,
    1.0e12,
    1.000_000_1e12,
    3.5e38,
    -3.5e38,
    1.0e200,
    -1.0e200,
    f64::MAX,
    f64::MIN_POSITIVE,
    5.0e-324,
    1.0e-7,
    -1.0e-7,
];

pub(crate) fn value() -> impl Strategy<Value = f64> + Clone {
    prop_oneof![3 => -2.0..2.0f64, 1 => select(SPECIAL)]
}

/// A corruption of a valid file.
#[derive(Clone, Debug)]
pub(crate) enum Mutation {
    None,
    Truncate(Index),
    Flip(Vec<(Index, u8)>),
    Overwrite(Index, Vec<u8>),
}

pub(crate) fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        1 => Just(Mutation::None),
        2 => any::<Index>().prop_map(Mutation::Truncate),
        3 => prop::collection::vec((any::<Index>(), 1u8..), 1..8).prop_map(Mutation::Flip),
        2 => (any::<Index>(), prop::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(i, b)| Mutation::Overwrite(i, b)),
    ]
}

pub(crate) fn mutate(mut bytes: Vec<u8>, m: &Mutation) -> Vec<u8> {
    if bytes.is_empty() {
        return bytes;
    }
    let n = bytes.len();
    match m {
        Mutation::None => {}
        Mutation::Truncate(i) => bytes.truncate(i.index(n)),
        Mutation::Flip(flips) => {
            for (i, x) in flips {
                bytes[i.index(n)] ^= x;
            }
        }
        Mutation::Overwrite(i, b) => {
            for (d, v) in bytes[i.index(n)..].iter_mut().zip(b) {
                *d = *v;
            }
        }
    }
    bytes
}

/// Where the value of EXR header attribute `name` of type `ty` starts.
pub(crate) fn exr_attr(bytes: &[u8], name: &str, ty: &str) -> Option<usize> {
    let key = format!("{name}\0{ty}\0");
    let at = bytes.windows(key.len()).position(|w| w == key.as_bytes())?;
    Some(at + key.len() + 4)
}

pub(crate) fn put(bytes: &mut [u8], at: usize, v: &[u8]) {
    if let Some(d) = bytes.get_mut(at..at + v.len()) {
        d.copy_from_slice(v);
    }
}

fn crc32(data: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in data {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// Sets a PNG's IHDR fields (width, height, bit depth, colour type, interlace) and its CRC.
pub(crate) fn patch_ihdr(bytes: &mut [u8], w: u32, h: u32, depth: u8, colour: u8, interlace: u8) {
    put(bytes, 16, &w.to_be_bytes());
    put(bytes, 20, &h.to_be_bytes());
    put(bytes, 24, &[depth, colour]);
    put(bytes, 28, &[interlace]);
    let crc = crc32(&bytes[12..29]);
    put(bytes, 29, &crc.to_be_bytes());
}
