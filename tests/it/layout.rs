//! The source tree's arrows run one way (docs/layout.md): no circle of files that
//! import one another, and none of top-level modules. A module's files and its `mod.rs`
//! may use each other (a module's parts share its types); every other pair of files may
//! not, directly or around a circle. The command line (`main.rs`, `cli/`) is checked the
//! same way on its own. Imports are read from the text: `crate::`, `super::` and `self::`
//! paths (`use` trees included), names re-exported by `pub use` followed to their module;
//! a file's unit tests are left out.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

type Module = Vec<String>;

/// Every `.rs` file under `dir`, by module path relative to `root`.
fn modules(root: &Path, dir: &Path, out: &mut Vec<(Module, PathBuf)>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .expect("reads src/")
        .map(|e| e.expect("an entry").path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            modules(root, &p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            let rel = p.strip_prefix(root).expect("under src/").with_extension("");
            let mut parts: Module = rel
                .iter()
                .map(|s| s.to_string_lossy().into_owned())
                .collect();
            if matches!(
                parts.last().map(String::as_str),
                Some("mod" | "lib" | "main")
            ) {
                parts.pop();
            }
            out.push((parts, p));
        }
    }
}

/// The text without its unit tests and line comments.
fn code(path: &Path) -> String {
    let text = std::fs::read_to_string(path).expect("reads a source file");
    let text = match text.find("#[cfg(test)]\nmod tests") {
        Some(i) => &text[..i],
        None => &text[..],
    };
    let mut out = String::new();
    for line in text.lines() {
        let mut in_string = false;
        let mut prev = ' ';
        let mut end = line.len();
        for (i, c) in line.char_indices() {
            if c == '"' && prev != '\\' {
                in_string = !in_string;
            }
            if !in_string && c == '/' && prev == '/' {
                end = i - 1;
                break;
            }
            prev = c;
        }
        out.push_str(&line[..end]);
        out.push('\n');
    }
    out
}

fn is_ident(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_'
}

/// Parses a path or use tree starting at byte `i` of `t`, after `prefix`; pushes every
/// full path onto `out` and returns where it ends.
fn use_tree(t: &str, mut i: usize, prefix: &[String], out: &mut Vec<Module>) -> usize {
    let b = t.as_bytes();
    let skip_ws = |mut i: usize| {
        while i < b.len() && (b[i] as char).is_whitespace() {
            i += 1;
        }
        i
    };
    let mut segs = prefix.to_vec();
    loop {
        i = skip_ws(i);
        let start = i;
        while i < b.len() && (is_ident(b[i] as char) || b[i] == b'*') {
            i += 1;
        }
        if i > start {
            segs.push(t[start..i].to_string());
        }
        let j = skip_ws(i);
        if !t[j..].starts_with("::") {
            out.push(segs);
            return i;
        }
        i = skip_ws(j + 2);
        if b.get(i) == Some(&b'{') {
            i += 1;
            loop {
                i = skip_ws(i);
                if b.get(i) == Some(&b'}') {
                    return i + 1;
                }
                i = use_tree(t, i, &segs, out);
                i = skip_ws(i);
                if t[i..].starts_with("as ") {
                    i += 3;
                    while i < b.len() && (is_ident(b[i] as char) || b[i] == b' ') {
                        i += 1;
                    }
                }
                if b.get(i) == Some(&b',') {
                    i += 1;
                }
                if i >= b.len() {
                    return i;
                }
            }
        }
    }
}

/// Every `crate::`, `super::` and `self::` path in `t`.
fn paths(t: &str) -> Vec<Module> {
    let mut out = Vec::new();
    for key in ["crate::", "super::", "self::"] {
        for (i, _) in t.match_indices(key) {
            let before = t[..i].chars().next_back().unwrap_or(' ');
            if !is_ident(before) && before != ':' {
                use_tree(t, i, &[], &mut out);
            }
        }
    }
    out
}

struct Tree {
    files: BTreeMap<Module, PathBuf>,
    /// (module, name) -> the module a `pub use` there takes `name` from.
    reexports: BTreeMap<(Module, String), Module>,
}

impl Tree {
    /// The module file a path from `from` lands in: the longest prefix that is a module,
    /// followed through re-exports of the name after it.
    fn resolve(&self, from: &Module, path: &[String], follow: bool) -> Module {
        let mut base = from.clone();
        let mut i = 0;
        match path.first().map(String::as_str) {
            Some("crate") => {
                base.clear();
                i = 1;
            }
            Some("self") => i = 1,
            _ => {
                while path.get(i).map(String::as_str) == Some("super") {
                    base.pop();
                    i += 1;
                }
            }
        }
        while let Some(seg) = path.get(i) {
            let mut next = base.clone();
            next.push(seg.clone());
            if !self.files.contains_key(&next) {
                break;
            }
            base = next;
            i += 1;
        }
        let mut hops = 0;
        while let (true, Some(name)) = (follow && hops < 8, path.get(i)) {
            match self.reexports.get(&(base.clone(), name.clone())) {
                Some(m) if *m != base => base = m.clone(),
                _ => break,
            }
            hops += 1;
        }
        base
    }

    fn new(files: BTreeMap<Module, PathBuf>) -> Self {
        let mut tree = Tree {
            files,
            reexports: BTreeMap::new(),
        };
        let mut found = Vec::new();
        for (m, p) in &tree.files {
            let t = code(p);
            for (i, _) in t.match_indices("pub use ") {
                let mut out = Vec::new();
                use_tree(&t, i + "pub use ".len(), &[], &mut out);
                for path in out {
                    let Some(name) = path.last() else { continue };
                    let relative = !matches!(path[0].as_str(), "crate" | "super" | "self");
                    let full: Vec<String> = if relative {
                        std::iter::once("self".to_string())
                            .chain(path.iter().cloned())
                            .collect()
                    } else {
                        path.clone()
                    };
                    found.push((m.clone(), name.clone(), full));
                }
            }
        }
        for (m, name, full) in found {
            let target = tree.resolve(&m, &full[..full.len() - 1], false);
            tree.reexports.insert((m, name), target);
        }
        tree
    }

    /// file -> files it imports, itself left out.
    fn edges(&self) -> BTreeSet<(Module, Module)> {
        let mut edges = BTreeSet::new();
        for (m, p) in &self.files {
            for path in paths(&code(p)) {
                let to = self.resolve(m, &path, true);
                if to != *m {
                    edges.insert((m.clone(), to));
                }
            }
        }
        edges
    }
}

/// The circles of a graph (its strongly connected components of more than one node).
fn circles(edges: &BTreeSet<(Module, Module)>) -> Vec<Vec<Module>> {
    let nodes: BTreeSet<&Module> = edges.iter().flat_map(|(a, b)| [a, b]).collect();
    let reach = |from: &Module| {
        let mut seen = BTreeSet::new();
        let mut todo = vec![from.clone()];
        while let Some(n) = todo.pop() {
            for (a, b) in edges {
                if *a == n && seen.insert(b.clone()) {
                    todo.push(b.clone());
                }
            }
        }
        seen
    };
    let reaches: BTreeMap<&Module, BTreeSet<Module>> =
        nodes.iter().map(|&n| (n, reach(n))).collect();
    let mut out: Vec<Vec<Module>> = Vec::new();
    for &n in &nodes {
        let circle: Vec<Module> = nodes
            .iter()
            .filter(|&&m| reaches[n].contains(m) && reaches[m].contains(n))
            .map(|&m| m.clone())
            .collect();
        if circle.len() > 1 && !out.contains(&circle) {
            out.push(circle);
        }
    }
    out
}

fn name(m: &Module) -> String {
    if m.is_empty() {
        "(root)".into()
    } else {
        m.join("::")
    }
}

/// Files of `files` (one crate) and the circles among them and among their top-level
/// modules.
fn check(files: BTreeMap<Module, PathBuf>) -> Vec<String> {
    let tree = Tree::new(files);
    let edges = tree.edges();
    let nested = |a: &Module, b: &Module| a.starts_with(b) || b.starts_with(a);
    let between_files: BTreeSet<_> = edges
        .iter()
        .filter(|(a, b)| !nested(a, b))
        .cloned()
        .collect();
    let between_top: BTreeSet<_> = edges
        .iter()
        .filter(|(a, b)| !a.is_empty() && !b.is_empty() && a[0] != b[0])
        .map(|(a, b)| (vec![a[0].clone()], vec![b[0].clone()]))
        .collect();
    let mut problems = Vec::new();
    for (what, set) in [
        ("files", &between_files),
        ("top-level modules", &between_top),
    ] {
        for c in circles(set) {
            let arrows: Vec<String> = set
                .iter()
                .filter(|(a, b)| c.contains(a) && c.contains(b))
                .map(|(a, b)| format!("{} -> {}", name(a), name(b)))
                .collect();
            problems.push(format!("a circle of {what}: {}", arrows.join(", ")));
        }
    }
    problems
}

#[test]
fn imports_run_one_way() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut all = Vec::new();
    modules(&src, &src, &mut all);
    let is_bin = |m: &Module, p: &PathBuf| {
        p.ends_with("main.rs") || m.first().map(String::as_str) == Some("cli")
    };
    let (bin, lib): (BTreeMap<_, _>, BTreeMap<_, _>) =
        all.into_iter().partition(|(m, p)| is_bin(m, p));
    assert!(lib.len() > 50 && bin.len() > 5, "found the source files");
    let mut problems = check(lib);
    problems.extend(check(bin));
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn a_circle_is_found() {
    // the check itself: two files that import each other, and a re-export followed
    let dir = tempfile::tempdir().expect("a temporary folder");
    let src = dir.path();
    std::fs::write(
        src.join("lib.rs"),
        "pub mod a;\npub mod b;\npub use b::B;\n",
    )
    .unwrap();
    std::fs::write(src.join("a.rs"), "use crate::B;\npub struct A;\n").unwrap();
    std::fs::write(
        src.join("b.rs"),
        "use crate::{a::{self, A}};\npub struct B;\n",
    )
    .unwrap();
    let mut files = Vec::new();
    modules(src, src, &mut files);
    let problems = check(files.into_iter().collect());
    assert_eq!(problems.len(), 2, "{problems:?}");
    assert!(problems[0].contains("a -> b, b -> a"), "{problems:?}");
}

/// The repository's root.
fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Every `.rs` file under `dir` (relative to the root), sorted.
fn rust_files(dir: &str) -> Vec<PathBuf> {
    let base = root().join(dir);
    let mut out = Vec::new();
    let mut todo = vec![base];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).expect("reads a source folder") {
            let p = e.expect("an entry").path();
            if p.is_dir() {
                todo.push(p);
            } else if p.extension().is_some_and(|e| e == "rs") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

#[test]
fn each_file_holds_one_idea() {
    // a source file reads at one sitting; an example is a program a user copies whole
    let mut long = Vec::new();
    for (dir, most) in [
        ("src", 500),
        ("python/src", 500),
        ("tests", 500),
        ("benches", 500),
        ("xtask", 500),
        ("fuzz", 500),
        ("examples", 100),
    ] {
        for p in rust_files(dir) {
            let n = std::fs::read_to_string(&p).expect("reads").lines().count();
            if n > most {
                long.push(format!("{}: {n} lines (at most {most})", p.display()));
            }
        }
    }
    assert!(long.is_empty(), "{}", long.join("\n"));
}

/// The types a library file makes public: (name, file) for each `pub struct`, `pub enum`,
/// `pub trait` and `pub type`, unit tests left out.
fn public_types(p: &Path) -> Vec<String> {
    let mut out = Vec::new();
    for line in code(p).lines() {
        let t = line.trim_start();
        for kind in ["pub struct ", "pub enum ", "pub trait ", "pub type "] {
            if let Some(rest) = t.strip_prefix(kind) {
                let name: String = rest.chars().take_while(|&c| is_ident(c)).collect();
                out.push(name);
            }
        }
    }
    out
}

#[test]
fn no_two_public_types_share_a_name() {
    // a name in the library's API says which thing it is without its module's path
    let src = root().join("src");
    let mut seen: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for p in rust_files("src") {
        let rel = p.strip_prefix(&src).expect("under src/");
        if rel.starts_with("cli") || rel == Path::new("main.rs") {
            continue;
        }
        for name in public_types(&p) {
            seen.entry(name)
                .or_default()
                .push(rel.display().to_string());
        }
    }
    let twice: Vec<String> = seen
        .iter()
        .filter(|(_, files)| files.len() > 1)
        .map(|(name, files)| format!("{name}: {}", files.join(", ")))
        .collect();
    assert!(
        twice.is_empty(),
        "public types of one name:\n{}",
        twice.join("\n")
    );
}

#[test]
fn io_reads_and_writes_formats() {
    // io/ turns files into the scene types and back: it imports the scene types, the error,
    // the math beneath them and the built-in materials' names (a manifest names presets),
    // never what renders, edits, synthesises or runs the command line
    let allowed = [
        "camera", "envmap", "error", "io", "material", "normals", "presets", "raster", "scene",
        "spline",
    ];
    let src = root().join("src");
    let mut all = Vec::new();
    modules(&src, &src, &mut all);
    let files: BTreeMap<Module, PathBuf> = all
        .into_iter()
        .filter(|(m, p)| !p.ends_with("main.rs") && m.first().map(String::as_str) != Some("cli"))
        .collect();
    let tree = Tree::new(files);
    let wrong: Vec<String> = tree
        .edges()
        .into_iter()
        .filter(|(a, b)| a.first().map(String::as_str) == Some("io") && !b.is_empty())
        .filter(|(_, b)| !allowed.contains(&b[0].as_str()))
        .map(|(a, b)| format!("{} -> {}", name(&a), name(&b)))
        .collect();
    assert!(
        wrong.is_empty(),
        "io imports beyond formats:\n{}",
        wrong.join("\n")
    );
}
