//! The release command line (`matedit render`, `matedit grad`) timed as whole processes.

use std::process::Command;
use std::time::Instant;

use serde_json::{Value, json};

use crate::case::{Case, Gathered, Setup};
use crate::common::{Files, median, read_npy};
use crate::errors::{Got, Truth, errors};
use crate::report::print_row;

/// Runs a command to completion; its wall seconds, or its stderr's tail on failure.
pub fn run_timed(cmd: &mut Command) -> Result<f64, String> {
    let s = Instant::now();
    let out = cmd.output().map_err(|e| format!("cannot start: {e}"))?;
    let t = s.elapsed().as_secs_f64();
    if out.status.success() {
        Ok(t)
    } else {
        let err = String::from_utf8_lossy(&out.stderr);
        let tail: String = err.lines().rev().take(3).collect::<Vec<_>>().join(" | ");
        Err(format!("{}: {tail}", out.status))
    }
}

/// `matedit render` and `matedit grad` as whole processes: (render s, grad s) per rep, and
/// the errors of what they wrote.
pub fn time_cli(
    f: &Files,
    device: &str,
    threads: usize,
    reps: usize,
    truth: &Truth,
) -> Result<(Vec<f64>, Vec<f64>, Value, Value), String> {
    let bin = env!("CARGO_BIN_EXE_matedit");
    let image = f.dir.join(format!("cli_{device}.npy"));
    let grads = f.dir.join(format!("cli_{device}_grads"));
    let common = |sub: &str| {
        let mut c = Command::new(bin);
        c.arg(sub)
            .arg("--normals")
            .arg(&f.normals)
            .arg("--env")
            .arg(&f.env)
            .arg("--material")
            .arg(&f.material)
            .args(["--device", device, "--threads", &threads.to_string()]);
        c
    };
    let mut render = common("render");
    render.arg("-o").arg(&image);
    let mut grad = common("grad");
    grad.arg("--upstream")
        .arg(&f.upstream)
        .arg("-o")
        .arg(&grads);
    // warm-up: page cache, and a check that both work
    run_timed(&mut render).map_err(|e| format!("matedit render: {e}"))?;
    run_timed(&mut grad).map_err(|e| format!("matedit grad: {e}"))?;
    let (mut tr, mut tg) = (Vec::new(), Vec::new());
    for _ in 0..reps {
        tr.push(run_timed(&mut render)?);
        tg.push(run_timed(&mut grad)?);
    }
    // what the processes wrote, against the reference
    let img = read_npy(&image)?;
    let d_env = read_npy(&grads.join("d_env.npy"))?;
    let d_n = read_npy(&grads.join("d_normals.npy"))?;
    let ctrl_file = grads.join("d_material.json");
    let ctrl: Value = serde_json::from_slice(&std::fs::read(&ctrl_file).unwrap_or_default())
        .map_err(|e| format!("{}: {e}", ctrl_file.display()))?;
    let d_ctrl: Vec<f64> = ctrl["ctrl"]
        .as_array()
        .map(|a| a.iter().filter_map(Value::as_f64).collect())
        .unwrap_or_default();
    let e_fwd = errors(
        truth,
        Got {
            image: &img.data,
            grads: None,
        },
    );
    let e_fb = errors(
        truth,
        Got {
            image: &img.data,
            grads: Some((&d_env.data, &d_n.data, &d_ctrl)),
        },
    );
    Ok((tr, tg, e_fwd, e_fb))
}

/// The command-line binary's modification time, to notice a rebuild during the run (other
/// builds in the same target folder overwrite it).
pub fn cli_mtime() -> Option<std::time::SystemTime> {
    std::fs::metadata(env!("CARGO_BIN_EXE_matedit"))
        .and_then(|m| m.modified())
        .ok()
}

/// Every command-line device on one scene and material, its records kept in `out`: the
/// `cpu` device's (fwd, fb) median seconds.
pub fn run_cli(
    setup: &Setup,
    case: &Case,
    files: &Files,
    truth: &Truth,
    out: &mut Gathered,
) -> Option<(f64, f64)> {
    let (scene_name, material) = (case.scene_name, case.material);
    let mut cli_s: Option<(f64, f64)> = None;
    for device in setup.cli_devices {
        if cli_mtime() != out.cli_built {
            let n = format!(
                "warning: {} was rebuilt during this run; command-line timings from here on \
                 may be of other code",
                env!("CARGO_BIN_EXE_matedit")
            );
            println!("{n}");
            out.notes.push(n);
            out.cli_built = cli_mtime();
        }
        match time_cli(
            &files,
            device,
            setup.opts.threads,
            setup.opts.cli_reps,
            &truth,
        ) {
            Ok((tr, tg, e_fwd, e_fb)) => {
                let fb: Vec<f64> = tr.iter().zip(&tg).map(|(a, b)| a + b).collect();
                let path = format!("cli-{device}");
                let a = case.rec(&path, "fwd", tr.clone(), e_fwd);
                let mut b = case.rec(&path, "fb", fb, e_fb);
                b.extra
                    .insert("grad_process_median_s".into(), json!(median(&tg)));
                if *device == "cpu" {
                    cli_s = Some((a.median(), b.median()));
                }
                print_row(&a);
                print_row(&b);
                out.records.push(a);
                out.records.push(b);
            }
            Err(e) => {
                let n = format!("cli {device} {scene_name} {}: {e}", material.name);
                println!("{n}");
                out.notes.push(n);
            }
        }
    }
    cli_s
}
