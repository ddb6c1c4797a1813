//! The house rules of `src/`, checked from the source text (no GPU, no build of the crate):
//!
//! * imports point one way down the layers: shared leaves (`error`, `fileio`, `geom`) ← model
//!   (`terrain`, `db`, `freeform`, `volume`, `voxel`, `display`) ← `scene` ← `world` ← CPU reference
//!   (`cpu`) ← GPU passes (`gpu`) ← application (`app`) ← `main.rs`;
//! * no import cycle between two files of `src/`;
//! * no file over 800 lines and no function over 120 lines.
//!
//! Imports are the `use crate::…`/`use super::…` trees and the `crate::…`/`super::…` paths
//! written inline (and `relief::…` in `main.rs`). A path is resolved to the file that defines
//! the item, following `pub use` re-exports, so a module's facade does not count as a
//! dependency of the module on its children.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Layer of each top-level room of `src/`; an import may point to the same or a lower layer.
const LAYERS: &[(&str, u32)] = &[
    ("error", 0),
    ("fileio", 0),
    ("geom", 0),
    ("colour", 0),
    ("geodesy", 0),
    ("terrain", 1),
    ("db", 1),
    ("freeform", 1),
    ("volume", 1),
    ("voxel", 1),
    ("display", 1),
    ("cigi", 1),
    ("scene", 2),
    ("world", 3),
    ("cpu", 4),
    ("gpu", 5),
    ("app", 6),
    ("main", 7),
];
const MAX_FILE_LINES: usize = 800;
const MAX_FN_LINES: usize = 120;

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Ident(String),
    Colons,
    Open,
    Close,
    Comma,
    Semi,
    Star,
    Other(char),
}

/// Source text tokenised with comments, strings and char literals removed; each token
/// carries its 1-based line.
fn tokenize(src: &str) -> Vec<(Tok, usize)> {
    let b: Vec<char> = src.chars().collect();
    let (mut i, mut line, mut out) = (0, 1, Vec::new());
    while i < b.len() {
        let c = b[i];
        let next = b.get(i + 1).copied().unwrap_or('\0');
        if c == '\n' {
            line += 1;
            i += 1;
        } else if c == '/' && next == '/' {
            while i < b.len() && b[i] != '\n' {
                i += 1;
            }
        } else if c == '/' && next == '*' {
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
                    line += (b[i] == '\n') as usize;
                    i += 1;
                }
            }
        } else if c == 'r' && (next == '"' || next == '#') && !prev_is_ident(&b, i) {
            // Raw string r"…" or r#"…"#.
            let mut j = i + 1;
            let mut hashes = 0;
            while j < b.len() && b[j] == '#' {
                hashes += 1;
                j += 1;
            }
            if j < b.len() && b[j] == '"' {
                j += 1;
                loop {
                    if j >= b.len() {
                        break;
                    }
                    if b[j] == '"' && (0..hashes).all(|k| b.get(j + 1 + k) == Some(&'#')) {
                        j += 1 + hashes;
                        break;
                    }
                    line += (b[j] == '\n') as usize;
                    j += 1;
                }
                i = j;
            } else {
                out.push((Tok::Ident("r".into()), line));
                i += 1;
            }
        } else if c == '"' {
            i += 1;
            while i < b.len() && b[i] != '"' {
                if b[i] == '\\' {
                    i += 1;
                }
                line += (b.get(i) == Some(&'\n')) as usize;
                i += 1;
            }
            i += 1;
        } else if c == '\'' {
            // Char literal ('a', '\n', '\u{..}') or lifetime ('a).
            if next == '\\' {
                i += 2;
                while i < b.len() && b[i] != '\'' {
                    i += 1;
                }
                i += 1;
            } else if b.get(i + 2) == Some(&'\'') {
                i += 3;
            } else {
                i += 1;
                while i < b.len() && (b[i].is_alphanumeric() || b[i] == '_') {
                    i += 1;
                }
            }
        } else if c.is_alphabetic() || c == '_' {
            let s = i;
            while i < b.len() && (b[i].is_alphanumeric() || b[i] == '_') {
                i += 1;
            }
            out.push((Tok::Ident(b[s..i].iter().collect()), line));
        } else if c.is_ascii_digit() {
            while i < b.len() && (b[i].is_alphanumeric() || b[i] == '_' || b[i] == '.') {
                if b[i] == '.' && b.get(i + 1) == Some(&'.') {
                    break;
                }
                i += 1;
            }
        } else {
            let t = match c {
                ':' if next == ':' => {
                    i += 1;
                    Tok::Colons
                }
                '{' => Tok::Open,
                '}' => Tok::Close,
                ',' => Tok::Comma,
                ';' => Tok::Semi,
                '*' => Tok::Star,
                c if c.is_whitespace() => {
                    i += 1;
                    continue;
                }
                c => Tok::Other(c),
            };
            out.push((t, line));
            i += 1;
        }
    }
    out
}

fn prev_is_ident(b: &[char], i: usize) -> bool {
    i > 0 && (b[i - 1].is_alphanumeric() || b[i - 1] == '_')
}

fn ident(t: &Tok) -> Option<&str> {
    match t {
        Tok::Ident(s) => Some(s),
        _ => None,
    }
}

/// One `use` leaf or inline path, relative to the module it was written in.
#[derive(Clone, Debug)]
struct PathRef {
    /// Module path (from the crate root) the reference was written in.
    module: Vec<String>,
    segments: Vec<String>,
    /// `pub use`: a re-export, followed during resolution instead of counted as an edge.
    reexport: bool,
    line: usize,
}

struct SourceFile {
    rel: String,
    /// Module path of the file (`src/gpu/mod.rs` → `["gpu"]`, `main.rs` → `["main"]`).
    module: Vec<String>,
    lines: usize,
    refs: Vec<PathRef>,
    /// Items defined at the top of each module of the file (file module and inline modules).
    items: BTreeMap<Vec<String>, BTreeSet<String>>,
    /// Inline `mod name { … }` module paths.
    inline_mods: BTreeSet<Vec<String>>,
    /// (function name, first line, line count).
    functions: Vec<(String, usize, usize)>,
}

fn module_of(rel: &Path) -> Vec<String> {
    let mut parts: Vec<String> = rel
        .iter()
        .map(|p| p.to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().unwrap();
    match last.as_str() {
        "lib.rs" | "mod.rs" => {}
        "main.rs" if parts.is_empty() => parts.push("main".into()),
        other => parts.push(other.trim_end_matches(".rs").to_string()),
    }
    parts
}

/// Parses a use tree starting at `toks[*i]`, appending the full paths (prefix + leaf).
fn use_tree(toks: &[(Tok, usize)], i: &mut usize, prefix: Vec<String>, out: &mut Vec<Vec<String>>) {
    let mut path = prefix;
    loop {
        match toks.get(*i).map(|t| &t.0) {
            Some(Tok::Ident(s)) => {
                path.push(s.clone());
                *i += 1;
                if toks.get(*i).map(|t| &t.0) == Some(&Tok::Ident("as".into())) {
                    *i += 2;
                }
                if toks.get(*i).map(|t| &t.0) == Some(&Tok::Colons) {
                    *i += 1;
                    continue;
                }
                out.push(path);
                return;
            }
            Some(Tok::Star) => {
                *i += 1;
                path.push("*".into());
                out.push(path);
                return;
            }
            Some(Tok::Open) => {
                *i += 1;
                loop {
                    match toks.get(*i).map(|t| &t.0) {
                        Some(Tok::Close) => {
                            *i += 1;
                            return;
                        }
                        Some(Tok::Comma) => *i += 1,
                        None => return,
                        _ => use_tree(toks, i, path.clone(), out),
                    }
                }
            }
            _ => return,
        }
    }
}

fn parse(root: &Path, file: &Path) -> SourceFile {
    let rel_path = file.strip_prefix(root).unwrap();
    let rel = format!("src/{}", rel_path.display());
    let src = std::fs::read_to_string(file).unwrap();
    let toks = tokenize(&src);
    let module = module_of(rel_path);
    let is_main = module == ["main"];
    let mut refs = Vec::new();
    let mut items: BTreeMap<Vec<String>, BTreeSet<String>> = BTreeMap::new();
    let mut inline_mods = BTreeSet::new();
    let mut functions = Vec::new();
    // Stack of (module path, brace depth at which it opened) for inline modules.
    let mut mods: Vec<(Vec<String>, usize)> = vec![(module.clone(), 0)];
    // Open functions: (name, line, depth of their body).
    let mut fns: Vec<(String, usize, usize)> = Vec::new();
    let mut pending_fn: Option<(String, usize)> = None;
    let mut depth = 0usize;
    let mut i = 0;
    while i < toks.len() {
        let (t, line) = (&toks[i].0, toks[i].1);
        let here = mods.last().unwrap().0.clone();
        match t {
            Tok::Open => {
                depth += 1;
                if let Some((name, l)) = pending_fn.take() {
                    fns.push((name, l, depth));
                }
                i += 1;
            }
            Tok::Close => {
                if let Some(&(_, _, d)) = fns.last() {
                    if d == depth {
                        let (name, l, _) = fns.pop().unwrap();
                        functions.push((name, l, line - l + 1));
                    }
                }
                if mods.len() > 1 && mods.last().unwrap().1 == depth {
                    mods.pop();
                }
                depth = depth.saturating_sub(1);
                i += 1;
            }
            Tok::Semi => {
                pending_fn = None;
                i += 1;
            }
            Tok::Ident(w) if w == "use" => {
                let reexport = i > 0
                    && (toks[i - 1].0 == Tok::Ident("pub".into())
                        || toks[i - 1].0 == Tok::Other(')'));
                i += 1;
                let mut paths = Vec::new();
                use_tree(&toks, &mut i, Vec::new(), &mut paths);
                for segments in paths {
                    refs.push(PathRef {
                        module: here.clone(),
                        segments,
                        reexport,
                        line,
                    });
                }
            }
            Tok::Ident(w) if w == "fn" => {
                if let Some(name) = toks.get(i + 1).and_then(|t| ident(&t.0)) {
                    let top = fns.is_empty() && depth == mods.last().unwrap().1;
                    if top {
                        items
                            .entry(here.clone())
                            .or_default()
                            .insert(name.to_string());
                    }
                    pending_fn = Some((name.to_string(), line));
                }
                i += 2;
            }
            Tok::Ident(w)
                if matches!(
                    w.as_str(),
                    "struct" | "enum" | "trait" | "type" | "const" | "static" | "union" | "mod"
                ) && fns.is_empty()
                    && depth == mods.last().unwrap().1 =>
            {
                if let Some(name) = toks.get(i + 1).and_then(|t| ident(&t.0)) {
                    items
                        .entry(here.clone())
                        .or_default()
                        .insert(name.to_string());
                    if w == "mod" && toks.get(i + 2).map(|t| &t.0) == Some(&Tok::Open) {
                        let mut m = here.clone();
                        m.push(name.to_string());
                        inline_mods.insert(m.clone());
                        mods.push((m, depth + 1));
                    }
                }
                i += 2;
            }
            Tok::Ident(w)
                if (w == "crate" || w == "super" || (is_main && w == "relief"))
                    && toks.get(i + 1).map(|t| &t.0) == Some(&Tok::Colons)
                    && !(i > 0 && toks[i - 1].0 == Tok::Colons) =>
            {
                let mut segments = vec![if w == "relief" {
                    "crate".to_string()
                } else {
                    w.clone()
                }];
                let mut j = i + 1;
                while toks.get(j).map(|t| &t.0) == Some(&Tok::Colons) {
                    match toks.get(j + 1).and_then(|t| ident(&t.0)) {
                        Some(s) => segments.push(s.to_string()),
                        None => break,
                    }
                    j += 2;
                }
                refs.push(PathRef {
                    module: here.clone(),
                    segments,
                    reexport: false,
                    line,
                });
                i = j;
            }
            _ => i += 1,
        }
    }
    // `use relief::…` in main.rs names the library crate.
    if is_main {
        for r in &mut refs {
            if r.segments.first().map(String::as_str) == Some("relief") {
                r.segments[0] = "crate".into();
            }
        }
    }
    SourceFile {
        rel,
        module,
        lines: src.lines().count(),
        refs,
        items,
        inline_mods,
        functions,
    }
}

struct Crate {
    files: Vec<SourceFile>,
    /// Module path → index of the file that holds it (file modules and inline modules).
    module_file: BTreeMap<Vec<String>, usize>,
}

impl Crate {
    fn load() -> Crate {
        let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("src");
        let mut paths = Vec::new();
        let mut stack = vec![root.clone()];
        while let Some(dir) = stack.pop() {
            for e in std::fs::read_dir(&dir).unwrap() {
                let p = e.unwrap().path();
                if p.is_dir() {
                    stack.push(p);
                } else if p.extension().is_some_and(|x| x == "rs") {
                    paths.push(p);
                }
            }
        }
        paths.sort();
        let files: Vec<SourceFile> = paths.iter().map(|p| parse(&root, p)).collect();
        let mut module_file = BTreeMap::new();
        for (k, f) in files.iter().enumerate() {
            module_file.insert(f.module.clone(), k);
            for m in &f.inline_mods {
                module_file.insert(m.clone(), k);
            }
        }
        Crate { files, module_file }
    }

    /// Absolute module path of a reference's segments (`crate`, `super`, `self` resolved).
    fn absolute(&self, r: &PathRef) -> Option<Vec<String>> {
        let mut segs = r.segments.iter().peekable();
        let mut base: Vec<String> = match segs.peek().map(|s| s.as_str()) {
            Some("crate") => {
                segs.next();
                Vec::new()
            }
            Some("super") | Some("self") => r.module.clone(),
            // `use std::…`, `use wgpu::…`, or a path relative to the current module.
            Some(first) => {
                let mut m = r.module.clone();
                m.push(first.to_string());
                if !self.module_file.contains_key(&m) {
                    return None;
                }
                r.module.clone()
            }
            None => return None,
        };
        while let Some(s) = segs.peek() {
            match s.as_str() {
                "super" => {
                    base.pop()?;
                }
                "self" => {}
                _ => break,
            }
            segs.next();
        }
        base.extend(segs.cloned());
        Some(base)
    }

    /// File that defines what `path` names, following `pub use` re-exports.
    fn resolve(&self, path: &[String], seen: &mut BTreeSet<Vec<String>>) -> Option<usize> {
        if !seen.insert(path.to_vec()) {
            return None;
        }
        // Longest prefix that is a module.
        let mut k = path.len();
        while k > 0 && !self.module_file.contains_key(&path[..k]) {
            k -= 1;
        }
        let module = &path[..k];
        let file = *self.module_file.get(module)?;
        if k == path.len() {
            return Some(file);
        }
        let name = &path[k];
        if name == "*" {
            return Some(file);
        }
        let f = &self.files[file];
        if f.items.get(module).is_some_and(|s| s.contains(name)) {
            return Some(file);
        }
        for r in f.refs.iter().filter(|r| r.reexport && r.module == module) {
            let Some(target) = self.absolute(r) else {
                continue;
            };
            if target.last() == Some(name) {
                if let Some(t) = self.resolve(&target, seen) {
                    return Some(t);
                }
            } else if target.last().map(String::as_str) == Some("*") {
                let mut via = target[..target.len() - 1].to_vec();
                via.push(name.clone());
                if let Some(t) = self.resolve(&via, seen) {
                    if t != file {
                        return Some(t);
                    }
                }
            }
        }
        Some(file)
    }

    /// Import edges between files: (from, to) → first line of the first import.
    fn edges(&self) -> BTreeMap<(usize, usize), usize> {
        let mut edges = BTreeMap::new();
        for (k, f) in self.files.iter().enumerate() {
            for r in f.refs.iter().filter(|r| !r.reexport) {
                let Some(abs) = self.absolute(r) else {
                    continue;
                };
                if let Some(t) = self.resolve(&abs, &mut BTreeSet::new()) {
                    if t != k {
                        edges.entry((k, t)).or_insert(r.line);
                    }
                }
            }
        }
        edges
    }

    fn layer(&self, file: usize) -> Result<u32, String> {
        let f = &self.files[file];
        let room = f.module.first().map(String::as_str).unwrap_or("");
        if room.is_empty() {
            return Ok(u32::MAX); // lib.rs: the crate root declares every room.
        }
        LAYERS
            .iter()
            .find(|(r, _)| *r == room)
            .map(|(_, l)| *l)
            .ok_or_else(|| {
                format!(
                    "{}: room `{room}` is not in tests/layers.rs LAYERS; give it a layer",
                    f.rel
                )
            })
    }
}

#[test]
fn imports_point_down_the_layers() {
    let c = Crate::load();
    let mut bad = Vec::new();
    for (&(from, to), &line) in &c.edges() {
        let (lf, lt) = match (c.layer(from), c.layer(to)) {
            (Ok(a), Ok(b)) => (a, b),
            (Err(e), _) | (_, Err(e)) => {
                bad.push(e);
                continue;
            }
        };
        if lf != u32::MAX && lt != u32::MAX && lt > lf {
            bad.push(format!(
                "{}:{line} imports {} (layer {lt} above layer {lf})",
                c.files[from].rel, c.files[to].rel
            ));
        }
    }
    bad.dedup();
    assert!(
        bad.is_empty(),
        "imports pointing up the layers:\n{}",
        bad.join("\n")
    );
}

#[test]
fn no_import_cycle_between_files() {
    let c = Crate::load();
    let edges = c.edges();
    let n = c.files.len();
    let mut adj = vec![Vec::new(); n];
    for &(a, b) in edges.keys() {
        adj[a].push(b);
    }
    let sccs = tarjan(&adj);
    let mut bad = Vec::new();
    for scc in sccs.iter().filter(|s| s.len() > 1) {
        let set: BTreeSet<usize> = scc.iter().copied().collect();
        let mut lines = vec![format!("cycle among {} files:", scc.len())];
        for (&(a, b), &line) in &edges {
            if set.contains(&a) && set.contains(&b) {
                lines.push(format!("  {}:{line} -> {}", c.files[a].rel, c.files[b].rel));
            }
        }
        bad.push(lines.join("\n"));
    }
    assert!(
        bad.is_empty(),
        "import cycles between files of src/:\n{}",
        bad.join("\n")
    );
}

/// Strongly connected components (Tarjan, iterative).
fn tarjan(adj: &[Vec<usize>]) -> Vec<Vec<usize>> {
    let n = adj.len();
    let (mut index, mut low) = (vec![usize::MAX; n], vec![0; n]);
    let (mut on, mut stack, mut out, mut next) = (vec![false; n], Vec::new(), Vec::new(), 0);
    for s in 0..n {
        if index[s] != usize::MAX {
            continue;
        }
        let mut work = vec![(s, 0usize)];
        while let Some(&mut (v, ref mut ei)) = work.last_mut() {
            if *ei == 0 && index[v] == usize::MAX {
                index[v] = next;
                low[v] = next;
                next += 1;
                stack.push(v);
                on[v] = true;
            }
            if let Some(&w) = adj[v].get(*ei) {
                *ei += 1;
                if index[w] == usize::MAX {
                    work.push((w, 0));
                } else if on[w] {
                    low[v] = low[v].min(index[w]);
                }
                continue;
            }
            work.pop();
            if let Some(&(u, _)) = work.last() {
                low[u] = low[u].min(low[v]);
            }
            if low[v] == index[v] {
                let mut comp = Vec::new();
                loop {
                    let w = stack.pop().unwrap();
                    on[w] = false;
                    comp.push(w);
                    if w == v {
                        break;
                    }
                }
                out.push(comp);
            }
        }
    }
    out
}

#[test]
fn files_and_functions_stay_small() {
    let c = Crate::load();
    let mut files: Vec<_> = c.files.iter().map(|f| (f.lines, f.rel.clone())).collect();
    files.sort_by(|a, b| b.cmp(a));
    let mut fns: Vec<_> = c
        .files
        .iter()
        .flat_map(|f| {
            f.functions
                .iter()
                .map(move |(n, l, len)| (*len, format!("{}:{l} {n}", f.rel)))
        })
        .collect();
    fns.sort_by(|a, b| b.cmp(a));
    println!("longest files:");
    for (n, f) in files.iter().take(5) {
        println!("  {n:5} {f}");
    }
    println!("longest functions:");
    for (n, f) in fns.iter().take(5) {
        println!("  {n:5} {f}");
    }
    let mut bad: Vec<String> = files
        .iter()
        .filter(|(n, _)| *n > MAX_FILE_LINES)
        .map(|(n, f)| format!("{f}: {n} lines (at most {MAX_FILE_LINES}): split it by purpose"))
        .collect();
    bad.extend(fns.iter().filter(|(n, _)| *n > MAX_FN_LINES).map(|(n, f)| {
        format!("{f}: function of {n} lines (at most {MAX_FN_LINES}): split it into steps")
    }));
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// The checker itself: a cycle and an upward import in a made-up crate are found.
#[test]
fn the_checker_finds_cycles_and_upward_imports() {
    let dir = std::env::temp_dir().join(format!("relief-layers-{}", std::process::id()));
    let src = dir.join("src");
    std::fs::create_dir_all(src.join("terrain")).unwrap();
    std::fs::create_dir_all(src.join("cpu")).unwrap();
    let write = |p: &str, s: &str| std::fs::write(src.join(p), s).unwrap();
    write(
        "terrain/mod.rs",
        "mod a;\npub use a::Height;\nuse crate::cpu::query; // up\n",
    );
    write(
        "terrain/a.rs",
        "/* use crate::cpu::x; */ pub struct Height; use super::b::B;\n",
    );
    write(
        "terrain/b.rs",
        "pub struct B; fn f() { let s = \"crate::cpu::x\"; super::Height; }\n",
    );
    write("cpu/mod.rs", "pub mod query;\n");
    write("cpu/query.rs", "use crate::terrain::Height;\n");
    let mut paths: Vec<PathBuf> = [
        "terrain/mod.rs",
        "terrain/a.rs",
        "terrain/b.rs",
        "cpu/mod.rs",
        "cpu/query.rs",
    ]
    .iter()
    .map(|p| src.join(p))
    .collect();
    paths.sort();
    let files: Vec<SourceFile> = paths.iter().map(|p| parse(&src, p)).collect();
    let mut module_file = BTreeMap::new();
    for (k, f) in files.iter().enumerate() {
        module_file.insert(f.module.clone(), k);
    }
    let c = Crate { files, module_file };
    let named: BTreeSet<(String, String)> = c
        .edges()
        .keys()
        .map(|&(a, b)| (c.files[a].rel.clone(), c.files[b].rel.clone()))
        .collect();
    let e = |a: &str, b: &str| (a.to_string(), b.to_string());
    // The re-export resolves to a.rs; comments and strings are not imports.
    assert!(
        named.contains(&e("src/cpu/query.rs", "src/terrain/a.rs")),
        "{named:?}"
    );
    assert!(
        named.contains(&e("src/terrain/mod.rs", "src/cpu/query.rs")),
        "{named:?}"
    );
    assert!(
        named.contains(&e("src/terrain/a.rs", "src/terrain/b.rs")),
        "{named:?}"
    );
    assert!(
        named.contains(&e("src/terrain/b.rs", "src/terrain/a.rs")),
        "{named:?}"
    );
    assert!(
        !named.contains(&e("src/terrain/a.rs", "src/cpu/mod.rs")),
        "{named:?}"
    );
    assert!(
        !named.iter().any(|(a, _)| a == "src/cpu/mod.rs"),
        "{named:?}"
    );
    let mut adj = vec![Vec::new(); c.files.len()];
    for &(a, b) in c.edges().keys() {
        adj[a].push(b);
    }
    assert!(tarjan(&adj).iter().any(|s| s.len() == 2));
    let up = c
        .edges()
        .keys()
        .any(|&(a, b)| c.layer(b).unwrap() > c.layer(a).unwrap());
    assert!(up, "terrain/mod.rs → cpu/query.rs points up");
    std::fs::remove_dir_all(&dir).ok();
}
