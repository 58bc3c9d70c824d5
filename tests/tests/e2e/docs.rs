//! The repository's shape: the documents' links resolve (every relative link of README.md,
//! CONTRIBUTING.md and docs/*.md names a file of the repository and, with `#anchor`, a heading of
//! that file), none of them names a path outside the repository, and no two source files of a
//! crate import each other, directly or round a longer loop.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ sits in the repository")
        .to_path_buf()
}

fn documents() -> Vec<PathBuf> {
    let mut out = vec![root().join("README.md"), root().join("CONTRIBUTING.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    docs.sort();
    out.extend(docs);
    out
}

/// A heading's anchor as GitHub makes it: lower case, spaces to hyphens, punctuation other than
/// hyphens and underscores dropped.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

/// The anchors of a Markdown file's headings (outside code blocks).
fn anchors(text: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut code = false;
    for line in text.lines() {
        if line.starts_with("```") {
            code = !code;
            continue;
        }
        if !code && line.starts_with('#') {
            out.insert(slug(line.trim_start_matches('#')));
        }
    }
    out
}

/// The targets of a Markdown file's inline links `](target)` (outside code blocks).
fn links(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut code = false;
    for line in text.lines() {
        if line.starts_with("```") {
            code = !code;
            continue;
        }
        if code {
            continue;
        }
        let mut rest = line;
        while let Some(i) = rest.find("](") {
            let after = &rest[i + 2..];
            let Some(end) = after.find(')') else { break };
            out.push(after[..end].to_string());
            rest = &after[end..];
        }
    }
    out
}

#[test]
fn every_relative_link_resolves() {
    let mut broken = Vec::new();
    for doc in documents() {
        let text = std::fs::read_to_string(&doc).unwrap();
        let dir = doc.parent().unwrap();
        for target in links(&text) {
            if target.starts_with("http://") || target.starts_with("https://") {
                continue;
            }
            let (file, anchor) = match target.split_once('#') {
                Some((f, a)) => (f, Some(a)),
                None => (target.as_str(), None),
            };
            let path = if file.is_empty() {
                doc.clone()
            } else {
                dir.join(file)
            };
            let Ok(path) = path.canonicalize() else {
                broken.push(format!("{}: {target}: no such file", doc.display()));
                continue;
            };
            if !path.starts_with(root().canonicalize().unwrap()) {
                broken.push(format!(
                    "{}: {target}: outside the repository",
                    doc.display()
                ));
                continue;
            }
            if let Some(a) = anchor {
                let heads = anchors(&std::fs::read_to_string(&path).unwrap_or_default());
                if !heads.contains(a) {
                    broken.push(format!("{}: {target}: no heading '#{a}'", doc.display()));
                }
            }
        }
    }
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}

#[test]
fn no_document_points_outside_the_repository() {
    for doc in documents() {
        let text = std::fs::read_to_string(&doc).unwrap();
        assert!(
            !text.contains("../shared"),
            "{} names a path outside the repository",
            doc.display()
        );
    }
}

#[test]
fn the_readme_is_a_front_door() {
    let text = std::fs::read_to_string(root().join("README.md")).unwrap();
    let lines = text.lines().count();
    assert!(lines <= 300, "README.md has {lines} lines");
    // the two commands of a fresh machine
    assert!(text.contains("cargo run --release -p v2x-sim -- run"));
    assert!(text.contains("cargo test --workspace --release"));
}

#[test]
fn slugs_as_github_makes_them() {
    assert_eq!(
        slug(" The paper's Table 2, reproduced"),
        "the-papers-table-2-reproduced"
    );
    assert_eq!(
        slug("Looking at a run (Foxglove)"),
        "looking-at-a-run-foxglove"
    );
    assert_eq!(slug("The method, and csba-wls+"), "the-method-and-csba-wls");
    assert_eq!(
        links("see [a](b.md#c) and [d](https://x)"),
        ["b.md#c", "https://x"]
    );
}

/// A crate's modules (by path, `a/b` for `a::b`) and the modules each one's code names through
/// `crate::` or `super::` (comments and `#[cfg(test)]` modules left out).
fn module_imports(krate: &str) -> std::collections::BTreeMap<String, BTreeSet<String>> {
    let src = root().join(krate).join("src");
    let mut files = Vec::new();
    let mut dirs = vec![src.clone()];
    while let Some(d) = dirs.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                dirs.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                files.push(p);
            }
        }
    }
    let mut code = std::collections::BTreeMap::new();
    for p in files {
        let rel = p.strip_prefix(&src).unwrap().with_extension("");
        let mut m = rel.to_string_lossy().replace('\\', "/");
        if let Some(parent) = m.strip_suffix("/mod") {
            m = parent.to_string();
        }
        if m == "tests" || m.ends_with("/tests") || m == "lib" || m == "main" {
            continue;
        }
        let text = std::fs::read_to_string(&p).unwrap();
        let text = text.split("#[cfg(test)]\nmod tests").next().unwrap_or("");
        let lines: Vec<&str> = text
            .lines()
            .filter(|l| !l.trim_start().starts_with("//"))
            .collect();
        code.insert(m, lines.join("\n"));
    }
    let modules: BTreeSet<String> = code.keys().cloned().collect();
    let mut graph = std::collections::BTreeMap::new();
    for (m, text) in &code {
        let parent = m.rsplit_once('/').map_or("", |(p, _)| p);
        let mut uses = BTreeSet::new();
        for (prefix, base) in [("crate::", String::new()), ("super::", parent.to_string())] {
            for (i, _) in text.match_indices(prefix) {
                let path: Vec<&str> = text[i + prefix.len()..]
                    .split(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
                    .next()
                    .unwrap_or("")
                    .split("::")
                    .collect();
                // the longest prefix of the path that names a module
                for k in (1..=path.len()).rev() {
                    let name = path[..k].join("/");
                    let full = if base.is_empty() {
                        name
                    } else {
                        format!("{base}/{name}")
                    };
                    if modules.contains(&full) {
                        if &full != m && !m.starts_with(&format!("{full}/")) {
                            uses.insert(full);
                        }
                        break;
                    }
                }
            }
        }
        graph.insert(m.clone(), uses);
    }
    graph
}

#[test]
fn no_import_cycle_between_files() {
    for krate in ["protocol", "fuser", "truth", "eval", "sim"] {
        let g = module_imports(krate);
        // Depth-first search for a back edge.
        fn visit(
            m: &str,
            g: &std::collections::BTreeMap<String, BTreeSet<String>>,
            state: &mut std::collections::BTreeMap<String, u8>,
            path: &mut Vec<String>,
        ) -> Option<Vec<String>> {
            state.insert(m.to_string(), 1);
            path.push(m.to_string());
            for n in g.get(m).into_iter().flatten() {
                match state.get(n.as_str()).copied().unwrap_or(0) {
                    1 => {
                        let at = path.iter().position(|p| p == n).unwrap();
                        let mut cycle = path[at..].to_vec();
                        cycle.push(n.clone());
                        return Some(cycle);
                    }
                    0 => {
                        if let Some(c) = visit(n, g, state, path) {
                            return Some(c);
                        }
                    }
                    _ => {}
                }
            }
            path.pop();
            state.insert(m.to_string(), 2);
            None
        }
        let mut state = std::collections::BTreeMap::new();
        for m in g.keys() {
            if state.get(m.as_str()).copied().unwrap_or(0) == 0 {
                if let Some(c) = visit(m, &g, &mut state, &mut Vec::new()) {
                    panic!("{krate}: files import each other: {}", c.join(" -> "));
                }
            }
        }
        assert!(g.len() >= 3, "{krate}: {} modules found", g.len());
    }
}
