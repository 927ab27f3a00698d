//! The core's imports run one way: each module of `src/` names only modules of its own layer or
//! a lower one, and no files import each other in a circle.
//!
//! Layers, lowest first (README "Architecture"):
//! `units`, `math`, `text`, `keys` and the crate root → `model` → `estimator`, `detect`, `ident` →
//! `control` → `config` → `console`. The firmware (`src/main.rs`, `src/board/`) is another
//! crate (the binary) above them all, which the library cannot name: it is not read here.
//!
//! The test reads `src/**/*.rs` as text (comments, strings and `#[cfg(test)]` modules left
//! out), resolves every `crate::`, `super::`, `self::` and child-module path to the file that
//! defines it (through the crate root's `pub use` re-exports), and then checks
//! - **layers**: no file names a file of a higher layer;
//! - **circles**: no files import each other in a loop. A child file naming its own parent
//!   module (`super::Estimator` from `estimator/pose.rs`) is the one exception: Rust gives a
//!   child its parent's private items, and a split module's impl blocks live there.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

/// The layers, lowest first: a module may name its own layer's modules and lower ones. `""` is
/// the crate root (`src/lib.rs`).
const LAYERS: [&[&str]; 6] = [
    &["", "units", "math", "text", "keys"],
    &["model"],
    &["estimator", "detect", "ident"],
    &["control"],
    &["config"],
    &["console"],
];

/// A source file of the library and what it names.
struct File {
    path: PathBuf,
    /// Module path (`["control", "config"]`; the root is empty).
    module: Vec<String>,
    /// The code without comments, strings and test modules.
    code: String,
}

/// An import from one file to another, with the names that make it.
type Edges = BTreeMap<(usize, usize), BTreeSet<String>>;

#[test]
fn core_imports_run_one_way_without_circles() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let report = check(&src);
    assert!(report.is_empty(), "src/ layering:\n{}", report.join("\n"));
}

/// The checker itself finds what it is for: an upward import and a circle, in a small tree.
#[test]
fn the_checker_finds_an_upward_import_and_a_circle() {
    let dir = std::env::temp_dir().join(format!("liftfw-layering-{}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    let write = |p: &str, text: &str| {
        let p = dir.join(p);
        fs::create_dir_all(p.parent().unwrap()).unwrap();
        fs::write(p, text).unwrap();
    };
    write(
        "lib.rs",
        "pub mod units;\npub mod model;\npub mod control;\n",
    );
    // units names model (a higher layer).
    write(
        "units.rs",
        "// crate::control::Nothing in a comment\npub fn f() -> crate::model::M { todo!() }\n",
    );
    write("model/mod.rs", "pub mod a;\npub mod b;\npub struct M;\n");
    // a and b name each other: a circle in one layer.
    write("model/a.rs", "use super::b::B;\npub struct A(B);\n");
    write("model/b.rs", "pub struct B(Box<crate::model::a::A>);\n#[cfg(test)]\nmod tests { use crate::control::C; }\n");
    write(
        "control/mod.rs",
        "pub struct C;\nuse crate::{model::M, units};\n",
    );
    let report = check(&dir);
    let _ = fs::remove_dir_all(&dir);
    let text = report.join("\n");
    assert!(
        text.contains("upward: src/units.rs (layer 0) -> src/model/mod.rs (layer 1): M"),
        "{text}"
    );
    assert!(
        text.contains("circle: src/model/a.rs, src/model/b.rs"),
        "{text}"
    );
    // Comments, test modules and downward imports are not findings.
    assert_eq!(report.len(), 2, "{text}");
}

/// Every finding, one line each (empty: the tree is layered and free of circles).
fn check(src: &Path) -> Vec<String> {
    let files = read_tree(src);
    let by_module: BTreeMap<Vec<String>, usize> = files
        .iter()
        .enumerate()
        .map(|(i, f)| (f.module.clone(), i))
        .collect();
    let reexports = root_reexports(&files);
    let mut edges = Edges::new();
    for (i, f) in files.iter().enumerate() {
        let children = child_modules(&f.code);
        for path in paths(&f.code) {
            let Some(abs) = absolute(&f.module, &children, &path) else {
                continue;
            };
            let Some((j, name)) = resolve(&by_module, &reexports, &abs) else {
                continue;
            };
            if j != i {
                edges.entry((i, j)).or_default().insert(name);
            }
        }
    }
    let name = |i: usize| {
        let p = files[i].path.strip_prefix(src).unwrap_or(&files[i].path);
        format!("src/{}", p.display())
    };
    let mut report = Vec::new();
    for (&(a, b), names) in &edges {
        let (la, lb) = (layer(&files[a].module), layer(&files[b].module));
        if lb > la {
            let names: Vec<&str> = names.iter().map(String::as_str).collect();
            report.push(format!(
                "upward: {} (layer {la}) -> {} (layer {lb}): {}",
                name(a),
                name(b),
                names.join(", ")
            ));
        }
    }
    // Circles: strongly connected components, without a child's edges to its ancestors.
    let graph: Vec<Vec<usize>> = (0..files.len())
        .map(|a| {
            edges
                .keys()
                .filter(|&&(x, y)| x == a && !is_ancestor(&files[y].module, &files[a].module))
                .map(|&(_, y)| y)
                .collect()
        })
        .collect();
    for scc in components(&graph) {
        if scc.len() > 1 {
            let mut names: Vec<String> = scc.iter().map(|&i| name(i)).collect();
            names.sort();
            let ties: Vec<String> = edges
                .iter()
                .filter(|(&(x, y), _)| {
                    scc.contains(&x) && scc.contains(&y) && graph[x].contains(&y)
                })
                .map(|(&(x, y), n)| {
                    let n: Vec<&str> = n.iter().map(String::as_str).collect();
                    format!("{} -> {} ({})", name(x), name(y), n.join(", "))
                })
                .collect();
            report.push(format!("circle: {}; {}", names.join(", "), ties.join("; ")));
        }
    }
    report
}

/// The layer of a module: that of its first segment. A module the table does not list fails
/// the test (a new top-level module must be placed).
fn layer(module: &[String]) -> usize {
    let top = module.first().map_or("", String::as_str);
    LAYERS
        .iter()
        .position(|l| l.contains(&top))
        .unwrap_or_else(|| panic!("module `{top}` is in no layer of LAYERS: place it"))
}

fn is_ancestor(a: &[String], b: &[String]) -> bool {
    a.len() < b.len() && b.starts_with(a)
}

/// The library's files: `src/**/*.rs` but the binary's (`main.rs`, `board/`) and modules
/// declared under `#[cfg(test)]`.
fn read_tree(src: &Path) -> Vec<File> {
    let mut out = Vec::new();
    let mut todo = vec![(src.join("lib.rs"), Vec::<String>::new())];
    while let Some((path, module)) = todo.pop() {
        let raw = fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let code = strip_tests(&strip_comments_and_strings(&raw));
        let dir = if module.is_empty() || path.ends_with("mod.rs") {
            path.parent().unwrap().to_path_buf()
        } else {
            path.with_extension("")
        };
        for child in child_modules(&code) {
            let mut m = module.clone();
            m.push(child.clone());
            let flat = dir.join(format!("{child}.rs"));
            let nested = dir.join(&child).join("mod.rs");
            let file = if flat.exists() { flat } else { nested };
            if file.exists() {
                todo.push((file, m));
            }
        }
        out.push(File { path, module, code });
    }
    out.sort_by(|a, b| a.path.cmp(&b.path));
    out
}

/// The code with comments, string and char literals blanked (so that a path in a doc comment
/// or a message is not an import). Lengths and line breaks are kept.
fn strip_comments_and_strings(s: &str) -> String {
    let b: Vec<char> = s.chars().collect();
    let mut out = String::with_capacity(s.len());
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
        } else if c == 'r'
            && (next == Some('"') || next == Some('#'))
            && !ident_char(b.get(i.wrapping_sub(1)).copied())
        {
            // Raw string: r"…", r#"…"#.
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
            loop {
                if j >= b.len() {
                    break;
                }
                if b[j] == '"' && (0..hashes).all(|k| b.get(j + 1 + k) == Some(&'#')) {
                    j += 1 + hashes;
                    break;
                }
                j += 1;
            }
            out.push_str("\"\"");
            i = j;
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

fn ident_char(c: Option<char>) -> bool {
    c.is_some_and(|c| c.is_alphanumeric() || c == '_')
}

/// The code without the items under `#[cfg(test)]` (or `#[cfg(all(test, …))]`): test modules
/// may name any layer.
fn strip_tests(code: &str) -> String {
    let mut out = String::new();
    let mut rest = code;
    while let Some(at) = find_test_attr(rest) {
        out.push_str(&rest[..at.0]);
        rest = &rest[at.1..];
        // Skip the item: up to its `;` or its balanced `{…}`.
        let mut depth = 0;
        let mut end = rest.len();
        for (k, ch) in rest.char_indices() {
            match ch {
                '{' | '[' | '(' => depth += 1,
                '}' | ']' | ')' => {
                    depth -= 1;
                    if depth == 0 && ch == '}' {
                        end = k + 1;
                        break;
                    }
                }
                ';' if depth == 0 => {
                    end = k + 1;
                    break;
                }
                _ => {}
            }
        }
        rest = &rest[end..];
    }
    out.push_str(rest);
    out
}

/// The span of the next `#[cfg(test)]`-like attribute.
fn find_test_attr(s: &str) -> Option<(usize, usize)> {
    let mut from = 0;
    while let Some(k) = s[from..].find("#[cfg(") {
        let start = from + k;
        let end = start + s[start..].find(")]")? + 2;
        let inner = &s[start + 6..end - 2];
        let words: Vec<&str> = inner
            .split(|c: char| !(c.is_alphanumeric() || c == '_'))
            .filter(|w| !w.is_empty())
            .collect();
        let test_only = inner.starts_with("test")
            || (inner.starts_with("all(")
                && words.contains(&"test")
                && !inner.contains("not(test"));
        if test_only {
            return Some((start, end));
        }
        from = end;
    }
    None
}

/// The modules a file declares (`mod x;`, `pub mod x;`, `pub(crate) mod x;`).
fn child_modules(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    for line in code.lines() {
        let t = line.trim();
        let t = t
            .strip_prefix("pub(crate) ")
            .or_else(|| t.strip_prefix("pub(super) "))
            .or_else(|| t.strip_prefix("pub "))
            .unwrap_or(t);
        if let Some(name) = t.strip_prefix("mod ").and_then(|r| r.strip_suffix(';')) {
            out.push(name.trim().to_string());
        }
    }
    out
}

/// Every path the code names: each `use` tree expanded (`a::{b, c::d}` → `a::b`, `a::c::d`),
/// and each `x::y…` path elsewhere.
fn paths(code: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let chars: Vec<char> = code.chars().collect();
    let mut i = 0;
    while i < chars.len() {
        let at_word = i == 0 || !ident_char(Some(chars[i - 1]));
        if at_word && starts_with(&chars, i, "use ") {
            let end = (i..chars.len())
                .find(|&k| chars[k] == ';')
                .unwrap_or(chars.len());
            let tree: String = chars[i + 4..end].iter().collect();
            expand(&tree, &mut Vec::new(), &mut out);
            i = end + 1;
            continue;
        }
        if at_word && (chars[i].is_alphabetic() || chars[i] == '_') {
            let mut segs = Vec::new();
            let mut k = i;
            loop {
                let s = k;
                while k < chars.len() && ident_char(Some(chars[k])) {
                    k += 1;
                }
                segs.push(chars[s..k].iter().collect::<String>());
                if starts_with(&chars, k, "::")
                    && chars
                        .get(k + 2)
                        .is_some_and(|c| c.is_alphabetic() || *c == '_')
                {
                    k += 2;
                } else {
                    break;
                }
            }
            if segs.len() > 1 {
                out.push(segs);
            }
            i = k.max(i + 1);
            continue;
        }
        i += 1;
    }
    out
}

fn starts_with(chars: &[char], i: usize, pat: &str) -> bool {
    pat.chars()
        .enumerate()
        .all(|(k, p)| chars.get(i + k) == Some(&p))
}

/// A `use` tree's paths, each with the prefix `pre`.
fn expand(tree: &str, pre: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
    let tree = tree.trim();
    if let Some(open) = tree.find('{') {
        let head: Vec<String> = tree[..open]
            .split("::")
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .map(String::from)
            .collect();
        let inner = &tree[open + 1..tree.rfind('}').unwrap_or(tree.len())];
        let n = pre.len();
        pre.extend(head);
        // Split at top-level commas.
        let mut depth = 0;
        let mut start = 0;
        for (k, c) in inner.char_indices() {
            match c {
                '{' => depth += 1,
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    expand(&inner[start..k], pre, out);
                    start = k + 1;
                }
                _ => {}
            }
        }
        expand(&inner[start..], pre, out);
        pre.truncate(n);
    } else if !tree.is_empty() {
        let first = tree.split(" as ").next().unwrap_or(tree);
        let mut p = pre.clone();
        p.extend(
            first
                .split("::")
                .map(str::trim)
                .filter(|s| !s.is_empty() && *s != "*")
                .map(String::from),
        );
        if p.last().is_some_and(|l| l == "self") {
            p.pop();
        }
        out.push(p);
    }
}

/// A path from `module` as an absolute module path, if it names this crate.
fn absolute(module: &[String], children: &[String], path: &[String]) -> Option<Vec<String>> {
    let first = path.first()?;
    let mut base: Vec<String>;
    let mut rest = path;
    match first.as_str() {
        "crate" => {
            base = Vec::new();
            rest = &path[1..];
        }
        "self" => {
            base = module.to_vec();
            rest = &path[1..];
        }
        "super" => {
            base = module.to_vec();
            while rest.first().is_some_and(|s| s == "super") {
                base.pop()?;
                rest = &rest[1..];
            }
        }
        name if children.iter().any(|c| c == name) => {
            base = module.to_vec();
        }
        _ => return None,
    }
    base.extend(rest.iter().cloned());
    Some(base)
}

/// The file that defines what an absolute path names (its longest module prefix; a name the
/// crate root re-exports, at that module), and the name.
fn resolve(
    by_module: &BTreeMap<Vec<String>, usize>,
    reexports: &BTreeMap<String, Vec<String>>,
    abs: &[String],
) -> Option<(usize, String)> {
    let mut n = abs.len();
    while n > 0 && !by_module.contains_key(&abs[..n]) {
        n -= 1;
    }
    let name = abs
        .get(n)
        .cloned()
        .unwrap_or_else(|| abs.last().cloned().unwrap_or_default());
    if n == 0 {
        if let Some(target) = abs.first().and_then(|first| reexports.get(first)) {
            return resolve(by_module, &BTreeMap::new(), target);
        }
    }
    Some((*by_module.get(&abs[..n])?, name))
}

/// The crate root's `pub use` re-exports: name → the absolute path it stands for.
fn root_reexports(files: &[File]) -> BTreeMap<String, Vec<String>> {
    let mut out = BTreeMap::new();
    let Some(root) = files.iter().find(|f| f.module.is_empty()) else {
        return out;
    };
    let children = child_modules(&root.code);
    for stmt in root.code.split(';') {
        let t = stmt.trim();
        let Some(tree) = t.strip_prefix("pub use ") else {
            continue;
        };
        let mut paths = Vec::new();
        expand(tree, &mut Vec::new(), &mut paths);
        for p in paths {
            if let (Some(last), Some(abs)) = (p.last(), absolute(&[], &children, &p)) {
                out.insert(last.clone(), abs);
            }
        }
    }
    out
}

/// Tarjan's strongly connected components.
fn components(graph: &[Vec<usize>]) -> Vec<Vec<usize>> {
    struct T<'a> {
        g: &'a [Vec<usize>],
        index: Vec<Option<usize>>,
        low: Vec<usize>,
        on: Vec<bool>,
        stack: Vec<usize>,
        next: usize,
        out: Vec<Vec<usize>>,
    }
    fn visit(t: &mut T<'_>, v: usize) {
        t.index[v] = Some(t.next);
        t.low[v] = t.next;
        t.next += 1;
        t.stack.push(v);
        t.on[v] = true;
        for &w in &t.g[v] {
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
            while let Some(w) = t.stack.pop() {
                t.on[w] = false;
                c.push(w);
                if w == v {
                    break;
                }
            }
            t.out.push(c);
        }
    }
    let n = graph.len();
    let mut t = T {
        g: graph,
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
