//! Around the readers: missing files and unknown extensions, staged writes, batch manifests.

use std::path::PathBuf;

use matedit::Convention;
use matedit::io;

use super::{dir, msg};

#[test]
fn missing_files_and_unknown_extensions() {
    let d = dir();
    let e = msg(io::load_normals(&d.path().join("nope.npy")).unwrap_err());
    assert!(e.ends_with("nope.npy: no such file"), "{e}");
    let e = msg(io::load_env(&d.path().join("sky.hdr"), Convention::Equirect).unwrap_err());
    assert!(e.contains("sky.hdr") && e.contains(".exr or .npy"), "{e}");
    let e = msg(
        io::check_output(&d.path().join("no/such/dir/out.exr"), &[io::Format::Exr]).unwrap_err(),
    );
    assert!(e.contains("does not exist"), "{e}");
}

#[test]
fn staged_writes_leave_nothing_when_dropped() {
    let d = dir();
    let p = d.path().join("out.npy");
    let s = io::stage(&p, b"data").unwrap();
    assert!(!p.exists());
    drop(s);
    assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 0);
    let s = io::stage(&p, b"data").unwrap();
    io::commit_all(vec![s]).unwrap();
    assert_eq!(std::fs::read(&p).unwrap(), b"data");
    assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 1);
}

#[test]
fn manifest_validation() {
    let d = dir();
    let p = d.path().join("batch.json");
    let write = |text: &str| std::fs::write(&p, text).unwrap();

    write(
        r#"{"env_size": "8x16", "scenes": [{"output": "a.exr", "sphere": 16, "preset": "gold"}, {"output": "b.npy", "normals": "n.npy", "env": "/abs/sky.exr"}]}"#,
    );
    let m = io::manifest::read(&p, None).unwrap();
    assert_eq!(m.scenes.len(), 2);
    assert_eq!(m.scenes[0].output, d.path().join("a.exr"));
    assert_eq!(m.scenes[1].env, Some(PathBuf::from("/abs/sky.exr")));
    let out = d.path().join("out");
    let m = io::manifest::read(&p, Some(&out)).unwrap();
    assert_eq!(m.scenes[1].output, out.join("b.npy"));

    let cases = [
        (r#"{"scenes": []}"#, "'scenes' is empty"),
        (
            r#"{"scenes": [{"output": "a.exr", "sphere": 4, "normals": "n.npy"}]}"#,
            "scenes[0]: give 'normals' or 'sphere'",
        ),
        (
            r#"{"scenes": [{"output": "a.exr", "preset": "unobtainium"}]}"#,
            "unknown preset 'unobtainium'",
        ),
        (
            r#"{"scenes": [{"output": "a.exr", "sphre": 4}]}"#,
            "scenes[0].sphre: unknown field `sphre`",
        ),
        (
            r#"{"scenes": [{"output": "a.exr"}, {"output": 5}]}"#,
            "scenes[1].output: invalid type: integer `5`",
        ),
        (r#"{"scenes": [{"sphere": 4}]}"#, "missing field `output`"),
        (
            r#"{"scenes": [{"output": "a.exr"}, {"output": "a.exr"}]}"#,
            "scenes[1]: output",
        ),
        (
            r#"{"env_size": "7", "scenes": [{"output": "a.exr"}]}"#,
            "env_size",
        ),
        (r#"{"fov": 200, "scenes": [{"output": "a.exr"}]}"#, "fov"),
        (r#"{"scenes": "#, "not a valid manifest"),
    ];
    for (text, want) in cases {
        write(text);
        let e = msg(io::manifest::read(&p, None).unwrap_err());
        assert!(e.contains("batch.json") && e.contains(want), "{text}: {e}");
    }
}
