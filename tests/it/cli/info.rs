//! The commands that describe rather than compute: `--help`, `presets` and `info`.

use matedit::io;

use super::{dir, env_texels, matedit, path_str, write_exr};

#[test]
fn help_has_examples_for_every_subcommand() {
    for sub in ["render", "grad", "info", "presets"] {
        let out = matedit().args([sub, "--help"]).output().unwrap();
        assert!(out.status.success());
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            text.contains("Examples:") && text.contains(&format!("matedit {sub}")),
            "{text}"
        );
    }
    let out = matedit().args(["render", "--help"]).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("reinhard") && text.contains("sRGB"),
        "tonemap documented"
    );
}

#[test]
fn presets_list_and_export() {
    let out = matedit().arg("presets").output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for p in matedit::presets::all() {
        assert!(text.contains(p.name) && text.contains(&p.description));
    }
    let d = dir();
    let out = matedit().args(["presets", "gold"]).output().unwrap();
    assert!(out.status.success());
    let p = d.path().join("gold.json");
    std::fs::write(&p, &out.stdout).unwrap();
    assert_eq!(
        io::load_material(&p).unwrap(),
        matedit::presets::lookup("gold").unwrap()
    );
}

#[test]
fn info_describes_inputs() {
    let d = dir();
    let env = d.path().join("env.exr");
    write_exr(&env, 32, 16, &env_texels());
    let out = matedit().args(["info", path_str(&env)]).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(
        text.contains("32 wide x 16 high") && text.contains("negative values: 14"),
        "{text}"
    );
    assert!(
        text.contains("env       yes: 14 negative values will be clamped"),
        "{text}"
    );

    let m = d.path().join("m.json");
    std::fs::write(&m, r#"{"ctrl": [1, 2]}"#).unwrap();
    let out = matedit().args(["info", path_str(&m)]).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(
        text.contains("material  no: 'ctrl' has 2 numbers"),
        "{text}"
    );
}
