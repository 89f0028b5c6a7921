//! The lod bench's report: the table on stdout, the checks of the tolerance runs, and
//! lod.json, lod.csv and the charts.

use std::path::Path;

use serde_json::{Value, json};

use crate::charts::{charts, register_font};
use crate::common::{self, median, write};
use crate::errors::{OUTPUTS, worst};
use crate::record::Rec;

/// A number as the table shows it: `1.2e-3`, `inf` or `-` (none).
pub fn sci(v: Option<f64>) -> String {
    match v {
        Some(x) if x.is_finite() => format!("{x:.1e}"),
        Some(_) => "inf".into(),
        None => "-".into(),
    }
}

/// A record's `stat` (max or mean) error of `output`.
pub fn err_of(r: &Rec, output: &str, stat: &str) -> Option<f64> {
    r.errors[output][stat].as_f64()
}

/// The table's header row.
pub fn header() {
    println!(
        "{:<30} {:>8} {:>3} {:>8} {:>8} | {:>8} {:>3} {:>8} {:>8} {:>8} {:>8} | {:>6} {:>8} {:>8}",
        "method",
        "fwd s",
        "n",
        "img max",
        "img mean",
        "fb s",
        "n",
        "img max",
        "d_env",
        "d_normal",
        "d_ctrl",
        "tol",
        "estimate",
        "wrong"
    );
}

/// One row: a method's fwd and fb records.
pub fn print_pair(a: &Rec, b: &Rec) {
    let tol = a.chosen.as_ref().map(|(t, _)| *t);
    let method = match (&a.chosen, &b.chosen) {
        (Some(_), Some((_, cb))) if cb.method.to_string() != a.method => {
            format!("{} / {}", a.method, cb.method)
        }
        _ => a.method.clone(),
    };
    let est = match (&a.chosen, &b.chosen) {
        (Some((_, ca)), Some((_, cb))) => {
            format!(
                "{}/{}",
                sci(Some(ca.estimate.max())),
                sci(Some(cb.estimate.max()))
            )
        }
        _ => "-".into(),
    };
    let wrong = match tol {
        Some(t) => {
            let w = |r: &Rec| if worst(&r.errors) > t { "WRONG" } else { "ok" };
            format!("{}/{}", w(a), w(b))
        }
        None => "-".into(),
    };
    println!(
        "{:<30} {:>8.4} {:>3} {:>8} {:>8} | {:>8.4} {:>3} {:>8} {:>8} {:>8} {:>8} | {:>6} {:>8} {:>8}",
        method,
        median(&a.times),
        a.reps,
        sci(err_of(a, "image", "max")),
        sci(err_of(a, "image", "mean")),
        median(&b.times),
        b.reps,
        sci(err_of(b, "image", "max")),
        sci(err_of(b, "d_env", "max")),
        sci(err_of(b, "d_normals", "max")),
        sci(err_of(b, "d_ctrl", "max")),
        tol.map_or("-".into(), |t| format!("{t:.0e}")),
        est,
        wrong
    );
}

/// Speed-ups against the exact run of the same scene and pass, and the checks of the
/// tolerance runs: (records, estimate wrong, slower than exact).
pub fn finish(records: Vec<Value>) -> (Vec<Value>, Vec<Value>, Vec<Value>) {
    let key = |r: &Value| {
        ["scene", "env", "material", "pass"].map(|k| r[k].as_str().unwrap_or("").to_string())
    };
    let exact: Vec<([String; 4], f64)> = records
        .iter()
        .filter(|r| r["method"] == "exact" && r["chosen_by_tol"] == false)
        .map(|r| (key(r), r["median_s"].as_f64().unwrap_or(f64::NAN)))
        .collect();
    let (mut wrong, mut slower) = (Vec::new(), Vec::new());
    let records: Vec<Value> = records
        .into_iter()
        .map(|mut r| {
            let k = key(&r);
            let t = r["median_s"].as_f64().unwrap_or(f64::NAN);
            if let Some((_, te)) = exact.iter().find(|(e, _)| *e == k) {
                r["speedup_vs_exact"] = json!(te / t);
                if r["chosen_by_tol"] == true {
                    r["slower_than_exact"] = json!(t > *te);
                }
            }
            let summary = || {
                json!({
                    "scene": r["scene"], "env": r["env"], "material": r["material"],
                    "pass": r["pass"], "tol": r["tol"], "method": r["method"],
                    "estimate": r["estimate"]["max"], "measured": r["err_max"],
                    "median_s": r["median_s"], "speedup_vs_exact": r["speedup_vs_exact"],
                })
            };
            if r["estimate_wrong"] == true {
                wrong.push(summary());
            }
            if r["slower_than_exact"] == true {
                slower.push(summary());
            }
            r
        })
        .collect();
    (records, wrong, slower)
}

/// The checks of the `tol_rows` tolerance runs: estimate wrong, slower than exact.
pub fn print_checks(wrong: &[Value], slower: &[Value], tol_rows: usize) {
    let row = |v: &Value| {
        format!(
            "  {} {} {} {} tol {}: {} estimated {} measured {} ({:.4} s, {:.2}x exact's speed)",
            v["scene"].as_str().unwrap_or(""),
            v["env"].as_str().unwrap_or(""),
            v["material"].as_str().unwrap_or(""),
            v["pass"].as_str().unwrap_or(""),
            sci(v["tol"].as_f64()),
            v["method"].as_str().unwrap_or(""),
            sci(v["estimate"].as_f64()),
            sci(v["measured"].as_f64()),
            v["median_s"].as_f64().unwrap_or(f64::NAN),
            v["speedup_vs_exact"].as_f64().unwrap_or(f64::NAN),
        )
    };
    println!(
        "\ncheck: {} of {tol_rows} tolerance runs measured an error above the tolerance \
         (estimate wrong){}",
        wrong.len(),
        if wrong.is_empty() { "" } else { ":" }
    );
    for v in wrong {
        println!("{}", row(v));
    }
    println!(
        "check: {} of {tol_rows} tolerance runs were slower than the exact layer{}",
        slower.len(),
        if slower.is_empty() { "" } else { ":" }
    );
    for v in slower {
        println!("{}", row(v));
    }
}

/// lod.csv: one row per record.
pub fn csv(records: &[Value]) -> String {
    let mut cols: Vec<String> = [
        "scene",
        "env",
        "material",
        "method",
        "family",
        "pass",
        "median_s",
        "reps",
        "speedup_vs_exact",
        "err_max",
    ]
    .map(String::from)
    .to_vec();
    for o in OUTPUTS {
        cols.push(format!("err_{o}_max"));
        cols.push(format!("err_{o}_mean"));
    }
    cols.extend(
        [
            "chosen_by_tol",
            "tol",
            "est_max",
            "est_image",
            "est_d_env",
            "est_d_normals",
            "est_d_ctrl",
            "predicted_cost",
            "choose_s",
            "estimate_wrong",
            "slower_than_exact",
        ]
        .map(String::from),
    );
    let cols: Vec<&str> = cols.iter().map(String::as_str).collect();
    common::csv(records, &cols, |r, c| {
        if let Some(k) = c.strip_prefix("est_") {
            &r["estimate"][k]
        } else if let Some(k) = c.strip_prefix("err_").filter(|k| *k != "max") {
            let (o, stat) = k.rsplit_once('_').unwrap_or((k, "max"));
            &r["errors"][o][stat]
        } else {
            &r[c]
        }
    })
}

/// lod.csv and the charts in `dir`, and lod.json unless the report was read from it.
pub fn write_outputs(report: &Value, dir: &Path, json_too: bool) {
    if let Err(e) = std::fs::create_dir_all(dir) {
        eprintln!("cannot create {}: {e}", dir.display());
        return;
    }
    let records = report["records"].as_array().cloned().unwrap_or_default();
    let tols: Vec<f64> = report["tols"]
        .as_array()
        .map(|t| t.iter().filter_map(Value::as_f64).collect())
        .unwrap_or_default();
    println!();
    if json_too {
        let jp = dir.join("lod.json");
        let text = serde_json::to_string_pretty(report).unwrap_or_default() + "\n";
        write(&jp, text.as_bytes());
        println!("wrote {}", jp.display());
    }
    let cp = dir.join("lod.csv");
    write(&cp, csv(&records).as_bytes());
    println!("wrote {}", cp.display());
    match register_font().and_then(|()| charts(&records, &tols, dir)) {
        Ok(paths) => {
            for p in paths {
                println!("wrote {}", p.display());
            }
        }
        Err(e) => println!("charts: {e}"),
    }
}
