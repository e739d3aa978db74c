//! The docs book (`docs/`, built by mdBook in `.ci/run`): every page is reached from its table
//! of contents, and every link between pages, and from README.md into the book, lands on a
//! file and, where it names one, on a heading of the page.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn src() -> PathBuf {
    root().join("docs/src")
}

/// Every Markdown page under `docs/src`, relative to it.
fn pages() -> BTreeSet<String> {
    fn walk(dir: &Path, base: &Path, out: &mut BTreeSet<String>) {
        for entry in std::fs::read_dir(dir).expect("read docs/src") {
            let path = entry.expect("entry").path();
            if path.is_dir() {
                walk(&path, base, out);
            } else if path.extension().is_some_and(|e| e == "md") {
                let rel = path.strip_prefix(base).expect("under docs/src");
                out.insert(rel.to_string_lossy().replace('\\', "/"));
            }
        }
    }
    let mut out = BTreeSet::new();
    walk(&src(), &src(), &mut out);
    out
}

/// A page's lines outside fenced code blocks.
fn prose(text: &str) -> impl Iterator<Item = &str> {
    let mut fenced = false;
    text.lines().filter(move |line| {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            return false;
        }
        !fenced
    })
}

/// The targets of inline Markdown links `[text](target)` outside code.
fn links(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    for line in prose(text) {
        // Inline code is not a link.
        let mut plain = String::new();
        for (i, part) in line.split('`').enumerate() {
            if i % 2 == 0 {
                plain.push_str(part);
            }
        }
        let mut rest = plain.as_str();
        while let Some(i) = rest.find("](") {
            let after = &rest[i + 2..];
            let Some(end) = after.find(')') else { break };
            out.push(after[..end].to_string());
            rest = &after[end..];
        }
    }
    out
}

/// The ids mdBook gives a page's headings (its `normalize_id`): letters, digits, `-` and `_`
/// kept, ASCII lower-cased, white space made `-`, everything else dropped; a repeated id gets
/// `-1`, `-2`, ….
fn heading_ids(text: &str) -> BTreeSet<String> {
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    let mut ids = BTreeSet::new();
    for line in prose(text).filter(|l| l.starts_with('#')) {
        let title = line.trim_start_matches('#').trim();
        let id: String = title
            .chars()
            .filter_map(|c| match c {
                c if c.is_alphanumeric() || c == '_' || c == '-' => Some(c.to_ascii_lowercase()),
                c if c.is_whitespace() => Some('-'),
                _ => None,
            })
            .collect();
        let n = seen.entry(id.clone()).or_insert(0);
        ids.insert(if *n == 0 {
            id.clone()
        } else {
            format!("{id}-{n}")
        });
        *n += 1;
    }
    ids
}

/// The pages SUMMARY.md links, in its order.
fn summary() -> Vec<String> {
    let text = std::fs::read_to_string(src().join("SUMMARY.md")).expect("docs/src/SUMMARY.md");
    links(&text)
}

#[test]
fn every_page_is_in_the_table_of_contents() {
    let listed: BTreeSet<String> = summary().into_iter().collect();
    let mut all = pages();
    all.remove("SUMMARY.md");
    let missing: Vec<_> = all.difference(&listed).collect();
    let absent: Vec<_> = listed.difference(&all).collect();
    assert!(
        missing.is_empty(),
        "pages not in docs/src/SUMMARY.md: {missing:?}"
    );
    assert!(
        absent.is_empty(),
        "SUMMARY.md lists pages that do not exist: {absent:?}"
    );
}

/// Checks one link from `from` (a file); returns what is wrong with it.
fn check(from: &Path, target: &str) -> Option<String> {
    if target.starts_with("http://")
        || target.starts_with("https://")
        || target.starts_with("mailto:")
    {
        return None;
    }
    let (file, anchor) = match target.split_once('#') {
        Some((f, a)) => (f, Some(a)),
        None => (target, None),
    };
    let path = match file {
        "" => from.to_path_buf(),
        f => from.parent().expect("a folder").join(f),
    };
    if !path.is_file() {
        return Some(format!("{target}: no file {}", path.display()));
    }
    let anchor = anchor?;
    if path.extension().is_none_or(|e| e != "md") {
        return None;
    }
    let text = std::fs::read_to_string(&path).expect("a page");
    match heading_ids(&text).contains(anchor) {
        true => None,
        false => Some(format!(
            "{target}: no heading #{anchor} in {}",
            path.display()
        )),
    }
}

#[test]
fn every_link_between_pages_lands_on_a_page_and_a_heading() {
    let mut wrong = Vec::new();
    let mut files: Vec<PathBuf> = pages().iter().map(|p| src().join(p)).collect();
    files.push(root().join("README.md"));
    let mut checked = 0;
    for file in &files {
        let text = std::fs::read_to_string(file).expect("a page");
        for target in links(&text) {
            checked += 1;
            if let Some(w) = check(file, &target) {
                wrong.push(format!(
                    "{}: {w}",
                    file.strip_prefix(root()).unwrap_or(file).display()
                ));
            }
        }
    }
    assert!(
        checked > 100,
        "only {checked} links found: the reader is broken"
    );
    assert!(wrong.is_empty(), "broken links:\n{}", wrong.join("\n"));
}

#[test]
fn the_readme_is_short_and_starts_with_the_two_commands() {
    let text = std::fs::read_to_string(root().join("README.md")).expect("README.md");
    let lines = text.lines().count();
    assert!(
        lines <= 300,
        "README.md has {lines} lines; the rest belongs in the book"
    );
    let first_block: Vec<&str> = text
        .lines()
        .skip_while(|l| !l.starts_with("```"))
        .skip(1)
        .take_while(|l| !l.starts_with("```"))
        .collect();
    assert!(
        first_block
            .iter()
            .any(|l| l.contains("render scenes/cornell-box/scene.json")),
        "README.md's first code block renders the Cornell box: {first_block:?}"
    );
    assert!(
        first_block
            .iter()
            .any(|l| l.trim_start().starts_with("cargo test --workspace")),
        "README.md's first code block runs the tests: {first_block:?}"
    );
}

#[test]
fn heading_ids_are_mdbooks() {
    let ids = heading_ids(
        "# Tessera\n## `auto`: choosing it\n## Each method's own error\n## A b\n## A b\n",
    );
    let want: BTreeSet<String> = [
        "tessera",
        "auto-choosing-it",
        "each-methods-own-error",
        "a-b",
        "a-b-1",
    ]
    .into_iter()
    .map(String::from)
    .collect();
    assert_eq!(ids, want);
}
