//! Determinism: the same bits across runs and thread counts, for every method and for the
//! choice for a tolerance.

use super::{ALWAYS, method, random_ortho, run, upstream};
use matedit::cpu::FastCpu;
use matedit::reference::Reference;

#[test]
fn results_are_deterministic_across_runs_and_threads() {
    let scene = random_ortho(25, (20, 18), (16, 32));
    let up = upstream(&scene, 26);
    let cpu = FastCpu::new().unwrap();
    let pool = |n: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
    };
    for m in ["exact", "env4", "table24+env2+keep4", "table16+keep8"].map(method) {
        let first = run(&Reference, &scene, &up, &m);
        assert_eq!(first, run(&Reference, &scene, &up, &m), "reference {m}");
        let one = pool(1).install(|| run(&cpu, &scene, &up, &m));
        let two = pool(2).install(|| (run(&cpu, &scene, &up, &m), run(&cpu, &scene, &up, &m)));
        assert_eq!(two.0, two.1, "cpu {m}: twice on 2 threads");
        assert_eq!(one, two.0, "cpu {m}: 1 vs 2 threads");
    }
    let within = |n: usize| {
        pool(n).install(|| {
            let (g, c) = ALWAYS.backward_within(&cpu, &scene, &up, 1e-2).unwrap();
            let (i, d) = ALWAYS.render_within(&cpu, &scene, 1e-2).unwrap();
            (g, c, i, d)
        })
    };
    assert_eq!(
        within(1),
        within(2),
        "the choices and their results, 1 vs 2 threads"
    );
}
