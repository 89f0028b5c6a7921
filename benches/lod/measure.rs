//! The timed runs of one scene: every method and tolerance on the fast CPU path, and the
//! peers.

use std::time::Instant;

use matedit::cpu::FastCpu;
use matedit::lod::{self, Method};
use serde_json::json;

use crate::Opts;
use crate::common;
use crate::errors::{errors, errors_of, flat};
use crate::record::{Case, Rec};
use crate::report::print_pair;

/// A run taking longer than this (seconds) is timed `Reps::long` times.
pub const LONG_S: f64 = 1.0;

/// How many timed runs: `n`, or `long` where the first took over [`LONG_S`].
#[derive(Clone, Copy)]
pub struct Reps {
    pub n: usize,
    pub long: usize,
}

/// Timed runs of `f` (see [`Reps`]), after a warm-up run if `warm_up`: the seconds and the
/// last result.
pub fn timed<T>(
    reps: Reps,
    warm_up: bool,
    mut f: impl FnMut() -> matedit::Result<T>,
) -> matedit::Result<(Vec<f64>, T)> {
    let mut last = if warm_up { Some(f()?) } else { None };
    let mut times: Vec<f64> = Vec::with_capacity(reps.n);
    let wanted = |t: &[f64]| match t.first() {
        Some(&first) if first > LONG_S => reps.long,
        _ => reps.n,
    };
    while times.len() < wanted(&times).max(1) {
        let s = Instant::now();
        last = Some(f()?);
        times.push(s.elapsed().as_secs_f64());
    }
    Ok((times, last.expect("at least one run")))
}

/// A pass pair's timings: `fwd` (after a warm-up if `warm_up`), then `fb`, whose render
/// the `fwd` runs have warmed (the median drops a slower first backward): seconds and last
/// results.
pub type Pair<A, B> = (Vec<f64>, A, Vec<f64>, B);

/// Times the pass pair [`Pair`] describes.
pub fn fwd_fb<A, B>(
    reps: Reps,
    warm_up: bool,
    fwd: impl FnMut() -> matedit::Result<A>,
    fb: impl FnMut() -> matedit::Result<B>,
) -> matedit::Result<Pair<A, B>> {
    let (tf, a) = timed(reps, warm_up, fwd)?;
    let (tb, b) = timed(reps, false, fb)?;
    Ok((tf, a, tb, b))
}

/// The exact run first (the errors' reference), then every other method and every
/// tolerance: their records, and the exact outputs.
pub fn measure(
    cpu: &FastCpu,
    case: &Case,
    opts: &Opts,
    notes: &mut Vec<String>,
) -> Option<(Vec<Rec>, [Vec<f64>; 4])> {
    let (scene, up) = (&case.scene, &case.upstream);
    let big = scene.normals.width * scene.normals.height >= 512 * 512;
    let reps = Reps {
        n: opts.reps,
        long: opts.big_reps.min(opts.reps),
    };
    // the exact and the tolerance runs of the 512 scenes are long: all of them
    let big_reps = if big {
        Reps {
            n: reps.long,
            ..reps
        }
    } else {
        reps
    };
    let run = |m: &Method, reps: Reps| {
        fwd_fb(
            reps,
            true,
            || lod::render(cpu, scene, m),
            || {
                let img = lod::render(cpu, scene, m)?;
                Ok((img, lod::backward(cpu, scene, up, m)?))
            },
        )
    };
    let (tf, tb, exact) = match run(&Method::EXACT, big_reps) {
        Ok((tf, _, tb, (img, g))) => (tf, tb, flat(&img, &g)),
        Err(e) => {
            let n = format!("{}: exact failed: {e}", case_name(case));
            println!("{n}");
            notes.push(n);
            return None;
        }
    };
    let zero = errors(&exact, &exact[0], Some([&exact[1], &exact[2], &exact[3]]));
    let mut recs = vec![
        case.rec("exact".into(), "fwd", tf, json!({"image": zero["image"]})),
        case.rec("exact".into(), "fb", tb, zero),
    ];
    print_pair(&recs[0], &recs[1]);
    for m in opts.methods.iter().filter(|m| !m.is_exact()) {
        let pair = run(m, reps).map(|(tf, img, tb, (img_b, g))| {
            (
                case.rec(m.to_string(), "fwd", tf, errors_of(&exact, &img, None)),
                case.rec(m.to_string(), "fb", tb, errors_of(&exact, &img_b, Some(&g))),
            )
        });
        push_pair(pair, &mut recs, notes, || {
            format!("{} {m}", case_name(case))
        });
    }
    for &tol in &opts.tols {
        // no warm-up: the methods before have run every kernel the choice and its plan use
        let pair = fwd_fb(
            big_reps,
            false,
            || lod::render_within(cpu, scene, tol),
            || {
                let (g, c) = lod::backward_within(cpu, scene, up, tol)?;
                Ok((lod::render(cpu, scene, &c.method)?, g, c))
            },
        )
        .and_then(|(tf, (img, cf), tb, (img_b, g, cb))| {
            let mut a = case.rec(
                cf.method.to_string(),
                "fwd",
                tf,
                errors_of(&exact, &img, None),
            );
            let mut b = case.rec(
                cb.method.to_string(),
                "fb",
                tb,
                errors_of(&exact, &img_b, Some(&g)),
            );
            // the choice alone, once: how much of the time it is
            for (r, c, up) in [(&mut a, cf, None), (&mut b, cb, Some(up))] {
                let s = Instant::now();
                lod::choose(cpu, scene, tol, up)?;
                r.extra
                    .insert("choose_s".into(), json!(s.elapsed().as_secs_f64()));
                r.chosen = Some((tol, c));
            }
            Ok((a, b))
        });
        push_pair(pair, &mut recs, notes, || {
            format!("{} tolerance {tol:e}", case_name(case))
        });
    }
    Some((recs, exact))
}

/// The scene, env map and material of a case, as the notes name it.
pub fn case_name(case: &Case) -> String {
    format!("{} {} {}", case.name, case.env, case.scene.material.name)
}

/// Prints and keeps a fwd and fb pair, or notes its failure.
pub fn push_pair(
    run: matedit::Result<(Rec, Rec)>,
    recs: &mut Vec<Rec>,
    notes: &mut Vec<String>,
    what: impl FnOnce() -> String,
) {
    match run {
        Ok((a, b)) => {
            print_pair(&a, &b);
            recs.push(a);
            recs.push(b);
        }
        Err(e) => {
            let n = format!("{}: failed: {e}", what());
            println!("{n}");
            notes.push(n);
        }
    }
}

/// The peers on one scene: their records, errors against `exact`.
pub fn measure_peers(
    case: &Case,
    peers: &[String],
    reps: usize,
    exact: &[Vec<f64>; 4],
    notes: &mut Vec<String>,
) -> Vec<Rec> {
    let files = common::write_inputs(&case.scene, &case.upstream, None);
    let res = match common::run_peers(&files, peers, reps) {
        Ok(r) => r,
        Err(e) => {
            let n = format!("peers {}: {e}", case_name(case));
            println!("{n}");
            notes.push(n);
            return Vec::new();
        }
    };
    let mut recs = Vec::new();
    for peer in peers {
        let r = &res[peer.as_str()];
        if let Some(err) = r.get("error") {
            let n = format!(
                "peer {peer} {}: failed: {}",
                case_name(case),
                err.as_str().unwrap_or("").replace('\n', " | ")
            );
            println!("{n}");
            notes.push(n);
            continue;
        }
        let (e_fwd, e_fb) = match common::read_peer_image(&files, peer) {
            Err(e) => (json!({"unread": e}), json!({"unread": e})),
            Ok(img) => {
                let fwd = errors(exact, &img, None);
                let fb = match common::read_peer_grads(&files, peer) {
                    Ok([e, n, c]) => errors(exact, &img, Some([&e, &n, &c])),
                    Err(common::Unread::File(e) | common::Unread::Arrays(e)) => {
                        json!({"unread": e})
                    }
                };
                (fwd, fb)
            }
        };
        let (Some(tf), Some(tb)) = (r["fwd"].as_f64(), r["fb"].as_f64()) else {
            continue;
        };
        let mut a = case.rec(format!("peer-{peer}"), "fwd", vec![tf], e_fwd);
        let mut b = case.rec(format!("peer-{peer}"), "fb", vec![tb], e_fb);
        a.reps = reps;
        b.reps = reps;
        print_pair(&a, &b);
        recs.push(a);
        recs.push(b);
    }
    recs
}
