//! The house rules of the crate, checked on its source: data flows one way through the stages
//! and no two files import each other, directly or around a circle.
//!
//! Every `src/**/*.rs` file is read; comments, strings and `#[cfg(test)]` items are dropped
//! (tests may reach anywhere); the `use` trees and the `crate::`, `super::`, `self::` and
//! child-module paths left are resolved to the file that defines the item, following `pub use`
//! re-exports to the file they come from. Two graphs are checked:
//!
//! * files of one directory: no import cycle (a `mod.rs` counts as a file of its directory);
//! * top-level modules: no cycle, and every import goes down the stage order of
//!   [`layer`], with `synth` and `validate` only reading the stages and only `main.rs`
//!   importing `cli`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The rank of a top-level module: a module may import modules of a lower rank only, and of
/// its own rank only inside the base (rank 0), where the cycle check keeps the order. `None`:
/// not a module the table knows (the test then fails naming it).
fn layer(module: &str) -> Option<u32> {
    Some(match module {
        // The base: shared by every stage, knowing none of them.
        "error" | "rng" | "anatomy" | "geometry" | "io" | "render" => 0,
        // The link tree, its frames and kinematics; the generic hand on it; the caliper
        // dimensions measured on any skin by their definitions (in the links' frames).
        "skeleton" => 1,
        "template" => 2,
        "measure" => 3,
        // The stages of the method, in the order the data flows.
        "mocap" => 4,
        "link" => 5,
        "skin" => 6,
        "tet" => 7,
        "pose" => 8,
        // One subject's stages from the trials to the skinned hand.
        "reconstruct" => 9,
        "grasp" => 10,
        // Replaying a captured motion with the individual hand (and its contacts).
        "track" => 11,
        // Readers of what the stages produce: the simulator and the validation.
        "synth" => 12,
        "validate" => 13,
        // The command jobs, over everything.
        "cli" => 14,
        // The crate root (re-exports) and the binary.
        "lib" => 15,
        "main" => 16,
        _ => return None,
    })
}

/// A module path from the crate root (`["pose", "quality"]`); the root is empty.
type ModPath = Vec<String>;

struct SourceFile {
    path: PathBuf,
    module: ModPath,
    /// Whether this file is a `mod.rs`/`lib.rs`/`main.rs` (its children are its own path).
    is_dir_module: bool,
    tokens: Vec<String>,
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// The module path of a file under `src/`.
fn module_of(rel: &Path) -> (ModPath, bool) {
    let mut parts: Vec<String> = rel
        .iter()
        .map(|s| s.to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().unwrap();
    let stem = last.trim_end_matches(".rs").to_string();
    match (parts.is_empty(), stem.as_str()) {
        (true, "lib") => (vec![], true),
        (true, "main") => (vec!["main".into()], true),
        (_, "mod") => (parts, true),
        _ => {
            parts.push(stem);
            (parts, false)
        }
    }
}

/// Source text without comments, string and char literals.
fn strip(src: &str) -> String {
    let b: Vec<char> = src.chars().collect();
    let mut out = String::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        let next = b.get(i + 1).copied();
        if c == '/' && next == Some('/') {
            while i < b.len() && b[i] != '\n' {
                i += 1;
            }
        } else if c == '/' && next == Some('*') {
            let mut depth = 0;
            while i < b.len() {
                if b[i] == '/' && b.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if b[i] == '*' && b.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
            out.push(' ');
        } else if c == 'r'
            && (next == Some('"') || next == Some('#'))
            && !b
                .get(i.wrapping_sub(1))
                .is_some_and(|p| p.is_alphanumeric() || *p == '_')
        {
            // A raw string r"..." or r#"..."#.
            let mut j = i + 1;
            let mut hashes = 0;
            while b.get(j) == Some(&'#') {
                hashes += 1;
                j += 1;
            }
            if b.get(j) != Some(&'"') {
                out.push(c);
                i += 1;
                continue;
            }
            j += 1;
            'raw: while j < b.len() {
                if b[j] == '"' && (0..hashes).all(|k| b.get(j + 1 + k) == Some(&'#')) {
                    j += 1 + hashes;
                    break 'raw;
                }
                j += 1;
            }
            i = j;
            out.push_str("\"\"");
        } else if c == '"' {
            i += 1;
            while i < b.len() && b[i] != '"' {
                if b[i] == '\\' {
                    i += 1;
                }
                i += 1;
            }
            i += 1;
            out.push_str("\"\"");
        } else if c == '\'' {
            // A char literal ('x', '\n', '\u{..}') or a lifetime ('a).
            if next == Some('\\') {
                let mut j = i + 2;
                while j < b.len() && b[j] != '\'' {
                    j += 1;
                }
                i = j + 1;
                out.push_str("' '");
            } else if b.get(i + 2) == Some(&'\'') {
                i += 3;
                out.push_str("' '");
            } else {
                out.push(c);
                i += 1;
            }
        } else {
            out.push(c);
            i += 1;
        }
    }
    out
}

/// Identifiers and the punctuation paths are made of.
fn tokenize(src: &str) -> Vec<String> {
    let b: Vec<char> = src.chars().collect();
    let mut t = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        if c.is_alphabetic() || c == '_' {
            let s = i;
            while i < b.len() && (b[i].is_alphanumeric() || b[i] == '_') {
                i += 1;
            }
            t.push(b[s..i].iter().collect());
        } else if c == ':' && b.get(i + 1) == Some(&':') {
            t.push("::".into());
            i += 2;
        } else if c.is_whitespace() {
            i += 1;
        } else {
            t.push(c.to_string());
            i += 1;
        }
    }
    t
}

/// The tokens without `#[cfg(test)]` items (a test module, a test helper).
fn drop_test_items(t: Vec<String>) -> Vec<String> {
    let is_cfg_test = |i: usize| {
        t.get(i..i + 7).is_some_and(|w| {
            w.iter().map(String::as_str).collect::<Vec<_>>()
                == ["#", "[", "cfg", "(", "test", ")", "]"]
        })
    };
    let mut out = Vec::new();
    let mut i = 0;
    while i < t.len() {
        if !is_cfg_test(i) {
            out.push(t[i].clone());
            i += 1;
            continue;
        }
        i += 7;
        // Up to the item's end: a `;` before any brace, or the matching closing brace.
        let mut depth = 0i32;
        while i < t.len() {
            match t[i].as_str() {
                ";" if depth == 0 => {
                    i += 1;
                    break;
                }
                "{" => depth += 1,
                "}" => {
                    depth -= 1;
                    if depth == 0 {
                        i += 1;
                        break;
                    }
                }
                _ => {}
            }
            i += 1;
        }
    }
    out
}

/// The paths of a `use` tree starting at `t[*i]`, up to its `;`, `,` or `}`.
fn use_tree(t: &[String], i: &mut usize, prefix: &[String], out: &mut Vec<Vec<String>>) {
    let mut path = prefix.to_vec();
    let mut is_self = false;
    while *i < t.len() {
        match t[*i].as_str() {
            "::" => *i += 1,
            "{" => {
                *i += 1;
                loop {
                    use_tree(t, i, &path, out);
                    match t.get(*i).map(String::as_str) {
                        Some(",") => *i += 1,
                        Some("}") => {
                            *i += 1;
                            break;
                        }
                        _ => break,
                    }
                    if t.get(*i).map(String::as_str) == Some("}") {
                        *i += 1;
                        break;
                    }
                }
                return;
            }
            "*" => {
                *i += 1;
                out.push(path.clone());
                return;
            }
            "as" => *i += 2,
            ";" | "," | "}" => {
                if !path.is_empty() && (path != prefix || is_self) {
                    out.push(path.clone());
                }
                return;
            }
            "self" if !path.is_empty() => {
                is_self = true;
                *i += 1;
            }
            s => {
                path.push(s.to_string());
                *i += 1;
            }
        }
    }
}

/// An import of one file: the written path, and whether it is a `pub use`.
struct Import {
    path: Vec<String>,
    public_use: bool,
}

/// Every path a file names: `use` trees, and `crate::`/`super::`/`self::` paths in code.
fn imports(t: &[String]) -> Vec<Import> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < t.len() {
        if t[i] == "use" && (i == 0 || t[i - 1] != "::") {
            let public_use = i > 0 && (t[i - 1] == "pub" || t[i - 1] == ")");
            i += 1;
            let mut paths = Vec::new();
            use_tree(t, &mut i, &[], &mut paths);
            out.extend(paths.into_iter().map(|path| Import { path, public_use }));
        } else if matches!(t[i].as_str(), "crate" | "super" | "self")
            && t.get(i + 1).map(String::as_str) == Some("::")
            && (i == 0 || t[i - 1] != "::")
        {
            let mut path = vec![t[i].clone()];
            let mut j = i + 1;
            while t.get(j).map(String::as_str) == Some("::")
                && t.get(j + 1)
                    .is_some_and(|s| s.starts_with(|c: char| c.is_alphabetic() || c == '_'))
            {
                path.push(t[j + 1].clone());
                j += 2;
            }
            out.push(Import {
                path,
                public_use: false,
            });
            i = j;
        } else {
            i += 1;
        }
    }
    out
}

/// The child modules a file declares (`mod x;`, `pub mod x;`).
fn declared_children(t: &[String]) -> BTreeSet<String> {
    (1..t.len())
        .filter(|&i| t[i - 1] == "mod" && t.get(i + 1).map(String::as_str) == Some(";"))
        .map(|i| t[i].clone())
        .collect()
}

struct Crate {
    files: Vec<SourceFile>,
    by_module: BTreeMap<ModPath, usize>,
    /// Per file: name -> absolute path of what its `pub use` re-exports.
    reexports: Vec<BTreeMap<String, Vec<String>>>,
}

impl Crate {
    fn load() -> Crate {
        let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
        let mut paths = Vec::new();
        rust_files(&src, &mut paths);
        let mut files = Vec::new();
        for p in paths {
            let rel = p.strip_prefix(&src).unwrap().to_path_buf();
            // Test modules kept in their own file (`#[cfg(test)] mod tests;`).
            if rel.file_name().is_some_and(|n| n == "tests.rs") {
                continue;
            }
            let (module, is_dir_module) = module_of(&rel);
            let text = std::fs::read_to_string(&p).unwrap();
            let tokens = drop_test_items(tokenize(&strip(&text)));
            files.push(SourceFile {
                path: PathBuf::from("src").join(rel),
                module,
                is_dir_module,
                tokens,
            });
        }
        let by_module = files
            .iter()
            .enumerate()
            .map(|(i, f)| (f.module.clone(), i))
            .collect();
        let mut c = Crate {
            files,
            by_module,
            reexports: Vec::new(),
        };
        c.reexports = (0..c.files.len())
            .map(|i| {
                imports(&c.files[i].tokens)
                    .into_iter()
                    .filter(|im| im.public_use)
                    .filter_map(|im| {
                        let abs = c.absolute(i, &im.path)?;
                        Some((im.path.last()?.clone(), abs))
                    })
                    .collect()
            })
            .collect();
        c
    }

    /// The module a file's own items live in, for `self::` and child paths.
    fn scope(&self, i: usize) -> ModPath {
        self.files[i].module.clone()
    }

    /// A written path made absolute; `None` for paths into other crates.
    fn absolute(&self, i: usize, path: &[String]) -> Option<Vec<String>> {
        let f = &self.files[i];
        let first = path.first()?;
        // The module `super` is relative to: a `mod.rs`'s own module, a leaf file's module.
        let mut base = self.scope(i);
        let mut rest = path;
        match first.as_str() {
            "crate" => {
                base.clear();
                rest = &path[1..];
            }
            "self" => rest = &path[1..],
            "super" => {
                while rest.first().map(String::as_str) == Some("super") {
                    base.pop()?;
                    rest = &rest[1..];
                }
            }
            name => {
                // A path starting at a child module of this file.
                let children = declared_children(&f.tokens);
                if !children.contains(name) {
                    return None;
                }
            }
        }
        let mut abs = base;
        abs.extend(rest.iter().cloned());
        Some(abs)
    }

    /// The file that defines what an absolute path names (following re-exports).
    fn target(&self, abs: &[String], depth: usize) -> Option<usize> {
        let (len, &file) = (0..=abs.len())
            .rev()
            .find_map(|n| self.by_module.get(&abs[..n]).map(|f| (n, f)))?;
        if depth < 8 {
            if let Some(next) = abs.get(len).and_then(|item| self.reexports[file].get(item)) {
                let mut p = next.clone();
                p.extend(abs[len + 1..].iter().cloned());
                if p != abs {
                    if let Some(t) = self.target(&p, depth + 1) {
                        return Some(t);
                    }
                }
            }
        }
        Some(file)
    }

    /// Per file: the files it imports, with the path written (for the failure message).
    fn edges(&self) -> Vec<BTreeMap<usize, String>> {
        (0..self.files.len())
            .map(|i| {
                let mut e = BTreeMap::new();
                // A `pub use` is the directory's front door, not a use: what it re-exports is
                // followed to its file by `target`.
                for im in imports(&self.files[i].tokens)
                    .iter()
                    .filter(|im| !im.public_use)
                {
                    let Some(abs) = self.absolute(i, &im.path) else {
                        continue;
                    };
                    let Some(t) = self.target(&abs, 0) else {
                        continue;
                    };
                    if t != i {
                        e.entry(t).or_insert_with(|| im.path.join("::"));
                    }
                }
                e
            })
            .collect()
    }

    fn top(&self, i: usize) -> String {
        self.files[i]
            .module
            .first()
            .cloned()
            .unwrap_or_else(|| "lib".into())
    }

    /// The directory a file belongs to (a `mod.rs` belongs to its own directory).
    fn dir(&self, i: usize) -> ModPath {
        let f = &self.files[i];
        if f.is_dir_module {
            f.module.clone()
        } else {
            f.module[..f.module.len() - 1].to_vec()
        }
    }
}

/// Cycles of a graph given as adjacency lists, one per strongly connected component with more
/// than one node (Tarjan's algorithm).
fn cycles(n: usize, adj: &[Vec<usize>]) -> Vec<Vec<usize>> {
    struct T<'a> {
        adj: &'a [Vec<usize>],
        index: Vec<Option<usize>>,
        low: Vec<usize>,
        on: Vec<bool>,
        stack: Vec<usize>,
        next: usize,
        out: Vec<Vec<usize>>,
    }
    fn visit(t: &mut T, v: usize) {
        t.index[v] = Some(t.next);
        t.low[v] = t.next;
        t.next += 1;
        t.stack.push(v);
        t.on[v] = true;
        for &w in &t.adj[v] {
            match t.index[w] {
                None => {
                    visit(t, w);
                    t.low[v] = t.low[v].min(t.low[w]);
                }
                Some(iw) if t.on[w] => t.low[v] = t.low[v].min(iw),
                _ => {}
            }
        }
        if Some(t.low[v]) == t.index[v] {
            let mut c = Vec::new();
            loop {
                let w = t.stack.pop().unwrap();
                t.on[w] = false;
                c.push(w);
                if w == v {
                    break;
                }
            }
            if c.len() > 1 {
                c.sort();
                t.out.push(c);
            }
        }
    }
    let mut t = T {
        adj,
        index: vec![None; n],
        low: vec![0; n],
        on: vec![false; n],
        stack: Vec::new(),
        next: 0,
        out: Vec::new(),
    };
    for v in 0..n {
        if t.index[v].is_none() {
            visit(&mut t, v);
        }
    }
    t.out
}

#[test]
fn no_import_cycle_between_files_of_a_directory() {
    let c = Crate::load();
    let edges = c.edges();
    let n = c.files.len();
    let adj: Vec<Vec<usize>> = (0..n)
        .map(|i| {
            edges[i]
                .keys()
                .copied()
                .filter(|&t| c.dir(t) == c.dir(i))
                .collect()
        })
        .collect();
    let mut problems = Vec::new();
    for cyc in cycles(n, &adj) {
        let members: BTreeSet<usize> = cyc.iter().copied().collect();
        let lines: Vec<String> = cyc
            .iter()
            .flat_map(|&a| {
                edges[a]
                    .iter()
                    .filter(|(b, _)| members.contains(b))
                    .map(|(&b, p)| {
                        format!(
                            "  {} imports {} (`{p}`)",
                            c.files[a].path.display(),
                            c.files[b].path.display()
                        )
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        problems.push(format!("an import cycle:\n{}", lines.join("\n")));
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn top_level_modules_import_down_the_stage_order_only() {
    let c = Crate::load();
    let edges = c.edges();
    let mut problems = Vec::new();
    let mut modules: Vec<String> = (0..c.files.len()).map(|i| c.top(i)).collect();
    modules.sort();
    modules.dedup();
    for m in &modules {
        if layer(m).is_none() {
            problems.push(format!(
                "src: module `{m}` has no place in the stage order (add it to `layer`)"
            ));
        }
    }
    for (i, e) in edges.iter().enumerate() {
        let (from, lf) = (c.top(i), layer(&c.top(i)));
        for (&t, path) in e {
            let (to, lt) = (c.top(t), layer(&c.top(t)));
            if from == to {
                continue;
            }
            let allowed = match (lf, lt) {
                (Some(a), Some(b)) => b < a || (a == 0 && b == 0),
                _ => true,
            };
            let cli_ok = to != "cli" || from == "main" || from == "lib";
            if !allowed || !cli_ok {
                problems.push(format!(
                    "{} imports `{path}`: `{from}` may not import `{to}` (stage order: {})",
                    c.files[i].path.display(),
                    "base (error, rng, anatomy, geometry, io, render) -> skeleton -> template \
                     -> measure -> mocap -> link -> skin -> tet -> pose -> grasp -> track -> synth -> \
                     validate -> cli -> main"
                ));
            }
        }
    }
    // No cycle between top-level modules (the base's members among themselves included).
    let idx: BTreeMap<&String, usize> = modules.iter().enumerate().map(|(k, m)| (m, k)).collect();
    let mut adj = vec![BTreeSet::new(); modules.len()];
    let mut witness = BTreeMap::new();
    for (i, e) in edges.iter().enumerate() {
        for (&t, path) in e {
            let (a, b) = (idx[&c.top(i)], idx[&c.top(t)]);
            if a != b {
                adj[a].insert(b);
                witness
                    .entry((a, b))
                    .or_insert_with(|| format!("{} imports `{path}`", c.files[i].path.display()));
            }
        }
    }
    let adj: Vec<Vec<usize>> = adj.into_iter().map(|s| s.into_iter().collect()).collect();
    for cyc in cycles(modules.len(), &adj) {
        let set: BTreeSet<usize> = cyc.iter().copied().collect();
        let lines: Vec<String> = witness
            .iter()
            .filter(|((a, b), _)| set.contains(a) && set.contains(b))
            .map(|(_, w)| format!("  {w}"))
            .collect();
        problems.push(format!(
            "an import cycle between modules {:?}:\n{}",
            cyc.iter().map(|&k| &modules[k]).collect::<Vec<_>>(),
            lines.join("\n")
        ));
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The parser itself, on a file whose imports are known.
#[test]
fn the_import_reader_resolves_use_trees_and_paths() {
    let t = drop_test_items(tokenize(&strip(
        r#"
        // use crate::commented::Out;
        use crate::io::{self, obj::{write_obj as w}, Units};
        use super::quality;
        fn f() { let s = "crate::in_string::X"; crate::geometry::mesh::TriMesh::new(); }
        #[cfg(test)]
        mod tests { use crate::synth::simulate; }
        "#,
    )));
    let got: Vec<String> = imports(&t).iter().map(|i| i.path.join("::")).collect();
    assert_eq!(
        got,
        [
            "crate::io",
            "crate::io::obj::write_obj",
            "crate::io::Units",
            "super::quality",
            "crate::geometry::mesh::TriMesh::new"
        ]
    );
    assert_eq!(
        module_of(Path::new("pose/mod.rs")),
        (vec!["pose".to_string()], true)
    );
    assert_eq!(
        module_of(Path::new("pose/quality.rs")),
        (vec!["pose".to_string(), "quality".to_string()], false)
    );
}
