//! The layer bench's records and their report: the table on stdout, the peers' ratios,
//! and layer.csv.

use matedit::gpu::PassTiming;
use serde_json::{Value, json};

use crate::common::{self, median};

/// One measurement: a path (or a command-line device, or a peer) on one scene and
/// material, one pass.
pub struct Rec {
    pub path: String,
    pub scene: String,
    pub material: String,
    pub pass: &'static str,
    pub times: Vec<f64>,
    /// Timed runs behind the median (peers report the median alone).
    pub reps: usize,
    pub pairs: f64,
    pub errors: Value,
    pub extra: serde_json::Map<String, Value>,
    /// GPU time per pass of the last call (in-process `gpu` path only).
    pub timings: Vec<PassTiming>,
}

impl Rec {
    pub fn median(&self) -> f64 {
        median(&self.times)
    }
    pub fn json(&self) -> Value {
        let m = self.median();
        let mut v = json!({
            "path": self.path, "scene": self.scene, "material": self.material,
            "pass": self.pass, "median_s": m, "reps": self.reps,
            "mpairs_per_s": self.pairs / m / 1e6, "errors": self.errors,
        });
        if let Value::Object(o) = &mut v {
            o.extend(self.extra.clone());
        }
        v
    }
}

/// The error `key` of a record's errors as the table shows it (`-`: none).
pub fn fmt_err(e: &Value, key: &str) -> String {
    match e.get(key).and_then(Value::as_f64) {
        Some(v) => format!("{v:.1e}"),
        None => "-".into(),
    }
}

/// One row of the table.
pub fn print_row(r: &Rec) {
    let m = r.median();
    println!(
        "{:<12} {:<10} {:<12} {:<4} {:>9.4} {:>3} {:>9.1} {:>8} {:>8} {:>8} {:>8}",
        r.path,
        r.scene,
        r.material,
        r.pass,
        m,
        r.reps,
        r.pairs / m / 1e6,
        fmt_err(&r.errors, "image"),
        fmt_err(&r.errors, "d_env"),
        fmt_err(&r.errors, "d_normals"),
        fmt_err(&r.errors, "d_ctrl"),
    );
}

/// The table's header row.
pub fn header() {
    println!(
        "{:<12} {:<10} {:<12} {:<4} {:>9} {:>3} {:>9} {:>8} {:>8} {:>8} {:>8}",
        "path",
        "scene",
        "material",
        "pass",
        "median s",
        "n",
        "Mpairs/s",
        "err img",
        "d_env",
        "d_normal",
        "d_ctrl"
    );
}

/// layer.csv: one row per record.
pub fn csv(records: &[Value]) -> String {
    let cols = [
        "path",
        "scene",
        "material",
        "pass",
        "median_s",
        "reps",
        "mpairs_per_s",
        "err_image",
        "err_d_env",
        "err_d_normals",
        "err_d_ctrl",
        "ratio_vs_cpu",
        "ratio_vs_cli",
    ];
    common::csv(records, &cols, |r, c| match c.strip_prefix("err_") {
        Some(k) => &r["errors"][k],
        None => &r[c],
    })
}

/// The peers' ratios against matedit (`ratios`: one per peer, scene and material).
pub fn print_ratios(ratios: &[Value]) {
    if ratios.is_empty() {
        return;
    }
    println!(
        "\nratios peer s / matedit s (> 1: matedit is faster); cpu = in-process Device::Cpu, \
         cli = whole `matedit render` (+ `grad`) processes"
    );
    println!(
        "{:<8} {:<10} {:<12} {:>9} {:>9} {:>9} {:>9} | {:>9} {:>9} {:>9} {:>9}",
        "peer",
        "scene",
        "material",
        "fwd s",
        "cpu s",
        "vs cpu",
        "vs cli",
        "fb s",
        "cpu s",
        "vs cpu",
        "vs cli"
    );
    let f = |v: &Value, d: usize| match v.as_f64() {
        Some(x) => format!("{x:.d$}"),
        None => "-".into(),
    };
    for r in ratios {
        println!(
            "{:<8} {:<10} {:<12} {:>9} {:>9} {:>9} {:>9} | {:>9} {:>9} {:>9} {:>9}",
            r["peer"].as_str().unwrap_or(""),
            r["scene"].as_str().unwrap_or(""),
            r["material"].as_str().unwrap_or(""),
            f(&r["fwd"]["peer_s"], 4),
            f(&r["fwd"]["cpu_s"], 4),
            f(&r["fwd"]["ratio_vs_cpu"], 3),
            f(&r["fwd"]["ratio_vs_cli"], 3),
            f(&r["fb"]["peer_s"], 4),
            f(&r["fb"]["cpu_s"], 4),
            f(&r["fb"]["ratio_vs_cpu"], 3),
            f(&r["fb"]["ratio_vs_cli"], 3),
        );
    }
}
