//! The peers (../shared/peers/time_peers.py) on one scene and material, and their errors.

use serde_json::{Value, json};

use crate::case::{Case, Gathered, Setup};
use crate::common::{self, Files, run_peers};
use crate::errors::{Got, Truth, errors};
use crate::report::print_row;

/// A peer's image and gradients (left beside the normals by time_peers.py) against the
/// reference: (fwd errors, fb errors).
pub fn peer_errors(f: &Files, peer: &str, truth: &Truth) -> (Value, Value) {
    let img = match common::read_peer_image(f, peer) {
        Ok(img) => img,
        Err(e) => return (json!({"unread": e}), json!({"unread": e})),
    };
    let fwd = errors(
        truth,
        Got {
            image: &img,
            grads: None,
        },
    );
    let fb = match common::read_peer_grads(f, peer) {
        Ok([e, n, c]) => errors(
            truth,
            Got {
                image: &img,
                grads: Some((&e, &n, &c)),
            },
        ),
        Err(common::Unread::Arrays(keys)) => json!({"unread": format!("arrays {keys}")}),
        Err(common::Unread::File(e)) => {
            let mut v = fwd.clone();
            v["grads_unread"] = json!(e);
            v
        }
    };
    (fwd, fb)
}

/// The peers on one scene and material, their records and their ratios against the
/// in-process `cpu` path (`cpu_s`) and the command line (`cli_s`) kept in `out`.
pub fn run_peers_of(
    setup: &Setup,
    case: &Case,
    files: &Files,
    truth: &Truth,
    (cpu_s, cli_s): (Option<(f64, f64)>, Option<(f64, f64)>),
    out: &mut Gathered,
) {
    let (scene_name, material) = (case.scene_name, case.material);
    if !setup.peers.is_empty() {
        match run_peers(&files, setup.peers, setup.opts.peer_reps) {
            Err(e) => {
                let n = format!("peers {scene_name} {}: {e}", material.name);
                println!("{n}");
                out.notes.push(n);
            }
            Ok(res) => {
                for peer in setup.peers {
                    let r = &res[peer.as_str()];
                    if let Some(err) = r.get("error") {
                        let n = format!(
                            "peer {peer} {scene_name} {}: failed: {}",
                            material.name,
                            err.as_str().unwrap_or("").replace('\n', " | ")
                        );
                        println!("{n}");
                        out.notes.push(n);
                        continue;
                    }
                    let (e_fwd, e_fb) = peer_errors(&files, peer, &truth);
                    let path = format!("peer-{peer}");
                    let mut ratio = json!({
                        "peer": peer, "scene": scene_name, "material": material.name,
                    });
                    for (pass, errs, idx) in [("fwd", e_fwd, 0), ("fb", e_fb, 1)] {
                        let Some(t) = r[pass].as_f64() else { continue };
                        let mut x = case.rec(&path, pass, vec![t], errs);
                        x.reps = setup.opts.peer_reps;
                        let pick = |v: (f64, f64)| if idx == 0 { v.0 } else { v.1 };
                        let vs_cpu = cpu_s.map(|c| t / pick(c));
                        let vs_cli = cli_s.map(|c| t / pick(c));
                        x.extra.insert("ratio_vs_cpu".into(), json!(vs_cpu));
                        x.extra.insert("ratio_vs_cli".into(), json!(vs_cli));
                        ratio[pass] = json!({
                            "peer_s": t, "cpu_s": cpu_s.map(pick), "cli_s": cli_s.map(pick),
                            "ratio_vs_cpu": vs_cpu, "ratio_vs_cli": vs_cli,
                        });
                        print_row(&x);
                        out.records.push(x);
                    }
                    out.ratios.push(ratio);
                }
            }
        }
    }
}
