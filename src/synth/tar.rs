//! Chunks as WebDataset-style tar files with reproducible bytes: ustar headers with mtime
//! 0, uid and gid 0, no user or group names, mode 0644, members sorted by name. Each
//! sample `k` is six members sharing the key `k` (zero-padded): `.env.npy`, `.image.npy`,
//! `.mask.npy`, `.material.json`, `.normals.npy` and `.params.json`; a spec with an `edit`
//! adds `.edit.npy` and `.edit_material.json` before them ([`super::edit`]).

use crate::error::{Error, Result};
use crate::scene::Image;

use super::draw::Sample;

/// The members of a sample, by suffix, in the order they are written.
pub const MEMBERS: [&str; 6] = [
    "env.npy",
    "image.npy",
    "mask.npy",
    "material.json",
    "normals.npy",
    "params.json",
];

/// Digits of a sample key: 8, or more for datasets of 10^8 samples or more.
pub fn key_width(count: u64) -> usize {
    count.saturating_sub(1).to_string().len().max(8)
}

/// A sample's members: (suffix, bytes) in [`MEMBERS`] order.
pub type Members = Vec<(&'static str, Vec<u8>)>;

/// A sample's key and members.
pub type Keyed = (String, Members);

/// The members of one rendered sample, in [`MEMBERS`] order.
pub fn members(sample: &Sample, image: &Image, renderer: &str) -> Members {
    let s = &sample.scene;
    let mut params = sample.params.clone();
    if let Some(o) = params.as_object_mut() {
        o.insert("renderer".into(), renderer.into());
    }
    let mut params_bytes = serde_json::to_vec_pretty(&params).unwrap_or_default();
    params_bytes.push(b'\n');
    vec![
        (
            MEMBERS[0],
            crate::io::npy::encode_rgb(s.env.width, s.env.height, &s.env.texels),
        ),
        (
            MEMBERS[1],
            crate::io::npy::encode_rgb(image.width, image.height, &image.pixels),
        ),
        (
            MEMBERS[2],
            crate::io::npy::encode_f32(
                &[s.normals.height, s.normals.width],
                &sample
                    .mask
                    .iter()
                    .map(|&m| if m { 1.0 } else { 0.0 })
                    .collect::<Vec<f32>>(),
            ),
        ),
        (
            MEMBERS[3],
            crate::io::json::encode_material(&s.material, None),
        ),
        (
            MEMBERS[4],
            crate::io::npy::encode_rgb(s.normals.width, s.normals.height, &s.normals.normals),
        ),
        (MEMBERS[5], params_bytes),
    ]
}

/// A tar file of `samples`, each `(key, members)`; keys ascending.
pub fn encode(samples: &[Keyed]) -> Result<Vec<u8>> {
    let fail = |e: std::io::Error| Error::Invalid(format!("tar: {e}"));
    let mut b = ::tar::Builder::new(Vec::new());
    b.mode(::tar::HeaderMode::Deterministic);
    for (key, members) in samples {
        for (suffix, bytes) in members {
            let mut h = ::tar::Header::new_ustar();
            h.set_path(format!("{key}.{suffix}")).map_err(fail)?;
            h.set_size(bytes.len() as u64);
            h.set_mode(0o644);
            h.set_mtime(0);
            h.set_uid(0);
            h.set_gid(0);
            h.set_username("").map_err(fail)?;
            h.set_groupname("").map_err(fail)?;
            h.set_entry_type(::tar::EntryType::Regular);
            h.set_cksum();
            b.append(&h, bytes.as_slice()).map_err(fail)?;
        }
    }
    b.into_inner().map_err(fail)
}

/// The members of a tar file as (name, bytes), in order.
pub fn decode(bytes: &[u8]) -> std::result::Result<Vec<(String, Vec<u8>)>, String> {
    use std::io::Read;
    let mut a = ::tar::Archive::new(bytes);
    let mut out = Vec::new();
    for entry in a.entries().map_err(|e| e.to_string())? {
        let mut entry = entry.map_err(|e| e.to_string())?;
        let name = entry
            .path()
            .map_err(|e| e.to_string())?
            .to_string_lossy()
            .into_owned();
        let mut data = Vec::new();
        entry.read_to_end(&mut data).map_err(|e| e.to_string())?;
        out.push((name, data));
    }
    Ok(out)
}
