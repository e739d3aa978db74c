//! The farm moves the core's tasks, results and artifacts without knowing one rendering
//! method from another (docs/src/design/overview.md: "the farm never names a method"): no method of the registry,
//! nor a pass or estimator of one, is named in the farm's source outside comments and tests.

use std::path::Path;

/// Words that would mean the farm knows a method: the registry's names (but `path` and
/// `direct`, which are also plain words) and what only a method knows.
fn forbidden() -> Vec<String> {
    let mut words: Vec<String> = tessera_render::method::names()
        .into_iter()
        .filter(|n| !matches!(*n, "path" | "direct" | "auto"))
        .map(String::from)
        .collect();
    words.extend(
        [
            "metropolis",
            "photon",
            "irradiance",
            "subsurface",
            "hierarchical",
            "dipole",
            "radii",
            "splat",
            "integrator::",
            "PathIntegrator",
        ]
        .map(String::from),
    );
    words
}

/// Source text without comments and without `#[cfg(test)]` modules.
fn code(text: &str) -> String {
    let mut out = String::new();
    let mut depth_in_test: Option<usize> = None;
    let mut depth = 0usize;
    let mut test_next = false;
    for line in text.lines() {
        let trimmed = line.trim_start();
        if trimmed.starts_with("#[cfg(test)]") {
            test_next = true;
            continue;
        }
        let code_part = match line.find("//") {
            Some(i) => &line[..i],
            None => line,
        };
        if test_next && code_part.contains('{') {
            depth_in_test = Some(depth);
            test_next = false;
        }
        depth += code_part.matches('{').count();
        depth = depth.saturating_sub(code_part.matches('}').count());
        if let Some(d) = depth_in_test {
            if depth <= d {
                depth_in_test = None;
            }
            continue;
        }
        out.push_str(code_part);
        out.push('\n');
    }
    out
}

fn sources(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for e in std::fs::read_dir(dir).expect("source dir").flatten() {
        let p = e.path();
        if p.is_dir() {
            sources(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

#[test]
fn the_farm_names_no_method() {
    let mut files = Vec::new();
    sources(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("src"),
        &mut files,
    );
    assert!(files.len() > 10, "{files:?}");
    let words = forbidden();
    let mut found = Vec::new();
    for f in &files {
        let text = std::fs::read_to_string(f).expect("read");
        let code = code(&text).to_lowercase();
        for w in &words {
            if code.contains(&w.to_lowercase()) {
                found.push(format!("{}: {w}", f.display()));
            }
        }
    }
    assert!(
        found.is_empty(),
        "method names in the farm's code: {found:#?}"
    );
}

#[test]
fn the_check_finds_a_name_in_code_but_not_in_comments_or_tests() {
    let text = "fn a() { let m = \"bdpt\"; }\n// sppm here\n#[cfg(test)]\nmod tests {\n    fn t() { vcm(); }\n}\n";
    let c = code(text);
    assert!(
        c.contains("bdpt") && !c.contains("sppm") && !c.contains("vcm"),
        "{c}"
    );
}
