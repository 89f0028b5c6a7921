//! Every WGSL module, as assembled on both tile kinds, parses and validates with naga and
//! has one entry point, named after its pass.

use super::module_with;
use matedit::gpu::{Pass, Tiles};

#[test]
fn every_pass_parses_and_validates() {
    for (pass, tiles) in Pass::ALL
        .into_iter()
        .flat_map(|p| [(p, Tiles::Workgroup), (p, Tiles::Uniform)])
    {
        let m = module_with(pass, tiles);
        assert!(
            m.entry_points.iter().any(|e| e.name == pass.name()),
            "{} has no entry point of its name",
            pass.name()
        );
        assert_eq!(
            m.entry_points.len(),
            1,
            "{}: one entry point per file",
            pass.name()
        );
    }
}
