//! The modules of each crate form layers at every depth: no two modules with the same parent
//! use each other, directly or through their siblings (a module may use its ancestors' items
//! and its own submodules). Read from the sources, without comments and test modules, so that
//! a new `use crate::…`, `super::…` or `self::…` that closes a cycle fails here with the cycle
//! named.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Every `.rs` file under `dir`.
fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("reading {}: {e}", dir.display()))
        .map(|e| e.expect("a directory entry").path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            sources(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// The code of a file without `//` comments and without what follows its first `#[cfg(test)]`
/// (test modules sit at the end of a file here).
fn code(text: &str) -> String {
    let text = text.split("#[cfg(test)]").next().unwrap_or("");
    text.lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n")
}

/// A file's module path inside its crate: `coordinator/api.rs` → `[coordinator, api]`,
/// `coordinator/mod.rs` → `[coordinator]`, `lib.rs` → `[]`.
fn module_of(rel: &Path) -> Vec<String> {
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().to_string())
        .collect();
    let last = parts.pop().expect("a file name");
    let stem = last.trim_end_matches(".rs");
    if !matches!(stem, "mod" | "lib" | "main") {
        parts.push(stem.to_string());
    }
    parts
}

/// The identifier at the start of `s`.
fn ident(s: &str) -> &str {
    let end = s
        .find(|c: char| !(c.is_alphanumeric() || c == '_'))
        .unwrap_or(s.len());
    &s[..end]
}

/// The paths named after a prefix such as `crate::`: `a::b::C` gives `[a, b, C]`; a group
/// `{a::b, c, self}` gives each entry's path (`self` and `*` the empty path: the prefix).
fn paths_after(s: &str) -> Vec<Vec<String>> {
    let s = s.trim_start();
    if let Some(group) = s.strip_prefix('{') {
        let mut depth = 0;
        let mut entries = Vec::new();
        let mut start = 0;
        for (i, c) in group.char_indices() {
            match c {
                '{' => depth += 1,
                '}' if depth == 0 => {
                    entries.push(&group[start..i]);
                    break;
                }
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    entries.push(&group[start..i]);
                    start = i + 1;
                }
                _ => {}
            }
        }
        return entries
            .into_iter()
            .flat_map(|e| match e.trim() {
                "" => Vec::new(),
                "self" | "*" => vec![Vec::new()],
                e => paths_after(e),
            })
            .collect();
    }
    let mut path = Vec::new();
    let mut rest = s;
    loop {
        let name = ident(rest);
        if name.is_empty() {
            break;
        }
        path.push(name.to_string());
        rest = &rest[name.len()..];
        match rest.strip_prefix("::") {
            Some(r) if r.starts_with('{') => {
                return paths_after(r)
                    .into_iter()
                    .map(|tail| path.iter().cloned().chain(tail).collect())
                    .collect();
            }
            Some(r) => rest = r,
            None => break,
        }
    }
    vec![path]
}

/// Every path a file's code names from its crate's root: `crate::…` as written, `super::…`
/// from its parent (once per `super`), `self::…` from itself.
fn named_paths(code: &str, module: &[String]) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    for prefix in ["crate::", "super::", "self::"] {
        for (i, _) in code.match_indices(prefix) {
            let before = code[..i].chars().next_back();
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
                continue; // `tessera_render::…` is another crate; `super::super::` is one path
            }
            let mut rest = &code[i + prefix.len()..];
            let mut base: Vec<String> = match prefix {
                "crate::" => Vec::new(),
                "self::" => module.to_vec(),
                _ => module[..module.len().saturating_sub(1)].to_vec(),
            };
            while let Some(r) = rest.strip_prefix("super::") {
                base.pop();
                rest = r;
            }
            for tail in paths_after(rest) {
                out.push(base.iter().cloned().chain(tail).collect());
            }
        }
    }
    out
}

/// For every module with submodules, the graph among its children: child → the children it
/// uses, from anywhere inside it. Keyed by the parent's path (`""` the crate's root).
type Graphs = BTreeMap<String, BTreeMap<String, BTreeSet<String>>>;

fn graphs(src: &Path) -> Graphs {
    let mut files = Vec::new();
    sources(src, &mut files);
    let modules: BTreeSet<Vec<String>> = files
        .iter()
        .map(|f| module_of(f.strip_prefix(src).expect("under src")))
        .collect();
    let mut g = Graphs::new();
    for m in &modules {
        if let Some((last, parent)) = m.split_last() {
            g.entry(parent.join("::"))
                .or_default()
                .entry(last.clone())
                .or_default();
        }
    }
    for f in &files {
        let module = module_of(f.strip_prefix(src).expect("under src"));
        let text = std::fs::read_to_string(f).expect("a source file");
        for named in named_paths(&code(&text), &module) {
            // The module named: the longest prefix of the path that is one (the rest are items).
            let target = (0..=named.len())
                .rev()
                .map(|n| named[..n].to_vec())
                .find(|p| p.is_empty() || modules.contains(p))
                .unwrap_or_default();
            let common = module
                .iter()
                .zip(&target)
                .take_while(|(a, b)| a == b)
                .count();
            // Using an ancestor's items or a descendant is no edge between siblings.
            if common == module.len() || common == target.len() {
                continue;
            }
            g.entry(module[..common].join("::"))
                .or_default()
                .entry(module[common].clone())
                .or_default()
                .insert(target[common].clone());
        }
    }
    g
}

/// A cycle through `start`, if there is one: the modules in order.
fn cycle_through(g: &BTreeMap<String, BTreeSet<String>>, start: &str) -> Option<Vec<String>> {
    let mut stack = vec![(start.to_string(), vec![start.to_string()])];
    let mut seen = BTreeSet::new();
    while let Some((node, path)) = stack.pop() {
        for next in g.get(&node).into_iter().flatten() {
            if next == start {
                return Some(path.clone());
            }
            if seen.insert(next.clone()) {
                let mut p = path.clone();
                p.push(next.clone());
                stack.push((next.clone(), p));
            }
        }
    }
    None
}

#[test]
fn no_module_has_an_import_cycle_between_its_submodules() {
    let crates = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut cycles = Vec::new();
    let mut modules = 0;
    for name in ["scene", "render", "farm", "tessera", "fuzz"] {
        for (parent, g) in graphs(&crates.join(name).join("src")) {
            modules += g.len();
            let at = match parent.as_str() {
                "" => name.to_string(),
                p => format!("{name}::{p}"),
            };
            for m in g.keys() {
                if let Some(c) = cycle_through(&g, m) {
                    cycles.push(format!("{at}: {} -> {m}", c.join(" -> ")));
                }
            }
        }
    }
    assert!(
        modules > 150,
        "read only {modules} modules: is the source tree where expected?"
    );
    assert!(cycles.is_empty(), "import cycles:\n{}", cycles.join("\n"));
}

#[test]
fn the_check_finds_a_cycle_when_there_is_one() {
    let mut g: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    g.entry("a".into()).or_default().insert("b".into());
    g.entry("b".into()).or_default().insert("c".into());
    g.entry("c".into()).or_default().insert("a".into());
    g.entry("d".into()).or_default().insert("a".into());
    assert_eq!(
        cycle_through(&g, "a"),
        Some(vec!["a".into(), "b".into(), "c".into()])
    );
    assert_eq!(cycle_through(&g, "d"), None);
    let code =
        code("use crate::x; // crate::y\nfn f() {}\n#[cfg(test)]\nmod tests { use crate::z; }");
    assert!(code.contains("crate::x") && !code.contains("crate::y") && !code.contains("crate::z"));
    let module = vec!["a".to_string(), "b".to_string()];
    let named = named_paths(
        "use super::{c::D, e}; use super::super::f::G; use crate::h::{i, j::K};",
        &module,
    );
    let named: Vec<String> = named.iter().map(|p| p.join("::")).collect();
    assert_eq!(named, ["h::i", "h::j::K", "a::c::D", "a::e", "f::G"]);
}
