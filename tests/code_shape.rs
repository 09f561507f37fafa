//! The shape of the code, checked on the source files:
//! - no import cycle between the modules (files) of a crate;
//! - no file of `crates/cli/src` over [`MAX_CLI_FILE_LINES`] lines;
//! - no function over [`MAX_FUNCTION_LINES`] lines anywhere in the workspace.
//!
//! The files and functions still over a limit are listed in [`LONG_FILES`] and
//! [`LONG_FUNCTIONS`]; an entry that no longer exceeds its limit fails the test too, so the
//! lists only shrink.
//!
//! How it counts:
//! - a module is a source file; `crate::a::b::…` (also inside `use crate::{…}` groups),
//!   `super::…` and `self::…` name the deepest module file the path reaches; an edge from a
//!   module to its ancestor or descendant (the `mod` tree itself) is not an import;
//! - a function runs from its `fn` line to the first line after it that is its closing brace at
//!   the `fn` line's indentation, both included (`rustfmt` puts it there); declarations without
//!   a body are not counted.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Longest file allowed in `crates/cli/src`.
const MAX_CLI_FILE_LINES: usize = 700;
/// Longest function allowed in the workspace.
const MAX_FUNCTION_LINES: usize = 150;

/// Files of `crates/cli/src` still over [`MAX_CLI_FILE_LINES`] (paths from the workspace root).
const LONG_FILES: &[&str] = &[];

/// Functions still over [`MAX_FUNCTION_LINES`]: `(file, function name)`.
const LONG_FUNCTIONS: &[(&str, &str)] = &[];

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the tests crate is in the workspace")
        .to_path_buf()
}

/// Every `.rs` file under `dir`, sorted, skipping build output.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in entries.flatten() {
            let p = e.path();
            let name = e.file_name();
            if p.is_dir() {
                if name != "target" && !name.to_string_lossy().starts_with('.') {
                    stack.push(p);
                }
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

fn relative(p: &Path) -> String {
    p.strip_prefix(root())
        .unwrap_or(p)
        .to_string_lossy()
        .replace('\\', "/")
}

/// The module path (`["commands", "sweep"]`) of a file under a crate's `src`.
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).expect("under src");
    let mut parts: Vec<String> = rel
        .iter()
        .map(|s| s.to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().expect("a file name");
    let stem = last.trim_end_matches(".rs");
    if !matches!(stem, "mod" | "lib" | "main") {
        parts.push(stem.to_string());
    }
    parts
}

/// The paths a file names from the crate root: `crate::…`, `super::…`, `self::…`, with the
/// groups of `use crate::{a, b::{c, d}}` expanded to their first segments.
fn named_paths(text: &str, module: &[String]) -> Vec<Vec<String>> {
    // the module that `super` and `self` start from (a `mod.rs` is its directory's module)
    let here: Vec<String> = module.to_vec();
    let mut out = Vec::new();
    let code: String = text
        .lines()
        .map(|l| match l.find("//") {
            Some(i) => &l[..i],
            None => l,
        })
        .collect::<Vec<_>>()
        .join("\n");
    let bytes = code.as_bytes();
    let is_ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    let mut i = 0;
    while i < bytes.len() {
        if !code.is_char_boundary(i) {
            i += 1;
            continue;
        }
        let rest = &code[i..];
        let start = if i > 0 { bytes[i - 1] } else { b' ' };
        let (base, skip): (Option<Vec<String>>, usize) = if is_ident(start) {
            (None, 0)
        } else if rest.starts_with("crate::") {
            (Some(Vec::new()), 7)
        } else if rest.starts_with("self::") {
            (Some(here.clone()), 6)
        } else if rest.starts_with("super::") {
            // super of a file module is its parent; chains of super go further up
            let mut b = here.clone();
            let mut k = 0;
            while code[i + k..].starts_with("super::") {
                b.pop();
                k += 7;
            }
            (Some(b), k)
        } else {
            (None, 0)
        };
        let Some(base) = base else {
            i += 1;
            continue;
        };
        i += skip;
        // the path's segments, or a group `{…}` of them
        if code[i..].starts_with('{') {
            let mut depth = 0;
            let mut j = i;
            for (k, c) in code[i..].char_indices() {
                if c == '{' {
                    depth += 1;
                } else if c == '}' {
                    depth -= 1;
                    if depth == 0 {
                        j = i + k;
                        break;
                    }
                }
            }
            let inner = &code[i + 1..j];
            // top-level items of the group
            let mut depth = 0;
            let mut item = String::new();
            for c in inner.chars().chain(std::iter::once(',')) {
                match c {
                    '{' => {
                        depth += 1;
                        item.push(c);
                    }
                    '}' => {
                        depth -= 1;
                        item.push(c);
                    }
                    ',' if depth == 0 => {
                        let segs: Vec<String> = item
                            .split("::")
                            .map(|s| s.trim().to_string())
                            .take_while(|s| !s.is_empty() && s.bytes().all(is_ident))
                            .collect();
                        if !segs.is_empty() {
                            let mut p = base.clone();
                            p.extend(segs);
                            out.push(p);
                        }
                        item.clear();
                    }
                    _ => item.push(c),
                }
            }
            i = j + 1;
        } else {
            let mut segs = Vec::new();
            let mut j = i;
            loop {
                let s = j;
                while j < bytes.len() && is_ident(bytes[j]) {
                    j += 1;
                }
                if j == s {
                    break;
                }
                segs.push(code[s..j].to_string());
                if code[j..].starts_with("::") && code[j + 2..].starts_with(|c: char| c != '{') {
                    j += 2;
                } else {
                    break;
                }
            }
            let mut p = base;
            p.extend(segs);
            out.push(p);
            i = j.max(i + 1);
        }
    }
    out
}

/// Cycles among the module files of one crate (each as a list of modules, the first repeated).
fn cycles(src: &Path) -> Vec<Vec<String>> {
    let files = rust_files(src);
    let modules: BTreeMap<Vec<String>, PathBuf> = files
        .iter()
        .map(|f| (module_of(src, f), f.clone()))
        .collect();
    let resolve = |path: &[String]| -> Vec<String> {
        (0..=path.len())
            .rev()
            .map(|n| path[..n].to_vec())
            .find(|p| modules.contains_key(p))
            .unwrap_or_default()
    };
    let related = |a: &[String], b: &[String]| a.starts_with(b) || b.starts_with(a);
    let mut edges: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> = BTreeMap::new();
    for (m, f) in &modules {
        let text = std::fs::read_to_string(f).expect("readable");
        for p in named_paths(&text, m) {
            let target = resolve(&p);
            if !related(m, &target) {
                edges.entry(m.clone()).or_default().insert(target);
            }
        }
    }
    // strongly connected components (Tarjan), reported as one cycle each
    let names: Vec<Vec<String>> = modules.keys().cloned().collect();
    let index_of: BTreeMap<&Vec<String>, usize> =
        names.iter().enumerate().map(|(i, n)| (n, i)).collect();
    let adj: Vec<Vec<usize>> = names
        .iter()
        .map(|n| {
            edges
                .get(n)
                .map(|s| s.iter().filter_map(|t| index_of.get(t).copied()).collect())
                .unwrap_or_default()
        })
        .collect();
    let mut t = Tarjan::new(adj);
    for v in 0..names.len() {
        if t.index[v] == usize::MAX {
            t.visit(v);
        }
    }
    t.components
        .into_iter()
        .map(|c| {
            let mut c: Vec<String> = c.iter().map(|&i| relative(&modules[&names[i]])).collect();
            c.sort();
            c
        })
        .collect()
}

/// Tarjan's strongly connected components of a directed graph; only those of two or more
/// vertices are kept.
struct Tarjan {
    adj: Vec<Vec<usize>>,
    index: Vec<usize>,
    low: Vec<usize>,
    on_stack: Vec<bool>,
    stack: Vec<usize>,
    next: usize,
    components: Vec<Vec<usize>>,
}

impl Tarjan {
    fn new(adj: Vec<Vec<usize>>) -> Self {
        let n = adj.len();
        Self {
            adj,
            index: vec![usize::MAX; n],
            low: vec![0; n],
            on_stack: vec![false; n],
            stack: Vec::new(),
            next: 0,
            components: Vec::new(),
        }
    }

    fn visit(&mut self, v: usize) {
        self.index[v] = self.next;
        self.low[v] = self.next;
        self.next += 1;
        self.stack.push(v);
        self.on_stack[v] = true;
        for k in 0..self.adj[v].len() {
            let w = self.adj[v][k];
            if self.index[w] == usize::MAX {
                self.visit(w);
                self.low[v] = self.low[v].min(self.low[w]);
            } else if self.on_stack[w] {
                self.low[v] = self.low[v].min(self.index[w]);
            }
        }
        if self.low[v] == self.index[v] {
            let mut comp = Vec::new();
            loop {
                let w = self.stack.pop().expect("on the stack");
                self.on_stack[w] = false;
                comp.push(w);
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                self.components.push(comp);
            }
        }
    }
}

/// Functions over [`MAX_FUNCTION_LINES`] in a file: `(name, first line, lines)`.
fn long_functions(text: &str) -> Vec<(String, usize, usize)> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    for (i, l) in lines.iter().enumerate() {
        let t = l.trim_start();
        let indent = l.len() - t.len();
        let mut words = t.split_whitespace();
        let mut name = None;
        while let Some(w) = words.next() {
            if w == "fn" {
                name = words.next().map(|n| {
                    n.split(|c: char| !(c.is_alphanumeric() || c == '_'))
                        .next()
                        .unwrap_or("")
                        .to_string()
                });
                break;
            }
            let qualifier = w.starts_with("pub")
                || matches!(
                    w,
                    "const" | "async" | "unsafe" | "extern" | "\"C\"" | "default"
                );
            if !qualifier {
                break;
            }
        }
        let Some(name) = name else { continue };
        // a body opens before a `;` ends a declaration
        let mut has_body = false;
        for m in &lines[i..] {
            if m.contains('{') {
                has_body = true;
                break;
            }
            if m.trim_end().ends_with(';') {
                break;
            }
        }
        if !has_body {
            continue;
        }
        let close = format!("{}}}", " ".repeat(indent));
        let end = lines[i + 1..]
            .iter()
            .position(|m| m.trim_end() == close)
            .map(|k| i + 1 + k)
            .unwrap_or(lines.len() - 1);
        // a one-line body ends on its own line
        let end = if l.trim_end().ends_with('}') && l.contains('{') {
            i
        } else {
            end
        };
        let n = end - i + 1;
        if n > MAX_FUNCTION_LINES {
            out.push((name, i + 1, n));
        }
    }
    out
}

fn workspace_sources() -> Vec<PathBuf> {
    let r = root();
    let mut files = rust_files(&r.join("crates"));
    files.extend(rust_files(&r.join("tests")));
    files.extend(rust_files(&r.join("fuzz")));
    files
}

#[test]
fn no_crate_has_an_import_cycle() {
    let r = root();
    let mut all = Vec::new();
    for krate in ["sens", "laminate", "section", "fem", "mbs", "cli"] {
        let src = r.join("crates").join(krate).join("src");
        for c in cycles(&src) {
            all.push(format!("{krate}: {}", c.join(" ↔ ")));
        }
    }
    assert!(all.is_empty(), "import cycles:\n{}", all.join("\n"));
}

#[test]
fn the_cycle_finder_sees_a_cycle() {
    // two sibling modules naming each other, one through a `use` group, one through `super`
    let dir = std::env::temp_dir().join(format!("flexsens_cycles_{}", std::process::id()));
    let src = dir.join("src");
    std::fs::create_dir_all(src.join("commands")).unwrap();
    std::fs::write(src.join("lib.rs"), "mod commands;\nmod other;\n").unwrap();
    std::fs::write(src.join("commands/mod.rs"), "mod a;\nmod b;\n").unwrap();
    std::fs::write(
        src.join("commands/a.rs"),
        "use crate::{other::X, commands::b::{f, g}};\n",
    )
    .unwrap();
    std::fs::write(src.join("commands/b.rs"), "fn h() { super::a::k(); }\n").unwrap();
    std::fs::write(
        src.join("other.rs"),
        "pub struct X; // crate::commands::a\n",
    )
    .unwrap();
    let found = cycles(&src);
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(found.len(), 1, "{found:?}");
    assert_eq!(found[0].len(), 2);
    assert!(found[0][0].ends_with("commands/a.rs") && found[0][1].ends_with("commands/b.rs"));
}

#[test]
fn cli_files_stay_short() {
    let r = root();
    let mut over = Vec::new();
    for f in rust_files(&r.join("crates/cli/src")) {
        let n = std::fs::read_to_string(&f).unwrap().lines().count();
        let name = relative(&f);
        let listed = LONG_FILES.contains(&name.as_str());
        if n > MAX_CLI_FILE_LINES && !listed {
            over.push(format!("{name}: {n} lines"));
        }
        if n <= MAX_CLI_FILE_LINES && listed {
            over.push(format!(
                "{name}: {n} lines, no longer long: remove it from LONG_FILES"
            ));
        }
    }
    assert!(over.is_empty(), "{}", over.join("\n"));
}

#[test]
fn functions_stay_short() {
    let mut over = Vec::new();
    let mut seen = BTreeSet::new();
    for f in workspace_sources() {
        let text = std::fs::read_to_string(&f).unwrap();
        let name = relative(&f);
        for (func, line, n) in long_functions(&text) {
            seen.insert((name.clone(), func.clone()));
            if !LONG_FUNCTIONS.contains(&(name.as_str(), func.as_str())) {
                over.push(format!("{name}:{line}: fn {func}: {n} lines"));
            }
        }
    }
    for (file, func) in LONG_FUNCTIONS {
        if !seen.contains(&(file.to_string(), func.to_string())) {
            over.push(format!(
                "{file}: fn {func} is no longer long: remove it from LONG_FUNCTIONS"
            ));
        }
    }
    assert!(over.is_empty(), "{}", over.join("\n"));
}

#[test]
fn the_function_counter_counts_to_the_closing_brace() {
    let body: String = (0..MAX_FUNCTION_LINES).map(|_| "    x += 1;\n").collect();
    let text = format!(
        "pub(crate) fn long(x: &mut i32) {{\n{body}}}\n\nfn short() {{}}\n\n    fn decl(&self);\n"
    );
    let found = long_functions(&text);
    assert_eq!(found, vec![("long".to_string(), 1, MAX_FUNCTION_LINES + 2)]);
}
