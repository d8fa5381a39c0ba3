//! The module map of `src/`, read from the code: which top-level module (folder or file) names which
//! through `crate::…` paths (comments and unit tests left out). Two rules of the house hold:
//!
//! - no folder imports a folder that imports it back, at any distance (the graph is acyclic);
//! - the stages that read a tree (`select`, `plan`, `render`, `inspect`, `store`, `paging`) read the model
//!   (`model`), not the preprocessor (`preprocess`).
//!
//! `tools/architecture.py` draws the same graph for the README.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Top-level module of a source file: `src/render/frame.rs` → `render`, `src/select.rs` → `select`.
fn top_module(src: &Path, file: &Path) -> Option<String> {
    let rel = file.strip_prefix(src).ok()?;
    let first = rel.components().next()?.as_os_str().to_str()?;
    let name = first.strip_suffix(".rs").unwrap_or(first);
    (name != "lib" && name != "main").then(|| name.to_string())
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let p = entry.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// Module → modules it names, with one place each (file:line) for the message.
fn module_graph() -> BTreeMap<String, BTreeMap<String, String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    files.sort();
    // Unit tests may use any stage to make their fixtures: they are not the module's dependencies. Test
    // code is a file named `tests.rs`, a file declared `#[cfg(test)] mod NAME;`, or the `#[cfg(test)]
    // `mod NAME {` that ends a file; any other item under `#[cfg(test)]` is refused (the scan could
    // not tell where it ends).
    let texts: Vec<String> = files
        .iter()
        .map(|f| std::fs::read_to_string(f).unwrap())
        .collect();
    let mut test_files = std::collections::BTreeSet::new();
    for (f, text) in files.iter().zip(&texts) {
        let lines: Vec<&str> = text.lines().map(str::trim).collect();
        for (ln, pair) in lines.windows(2).enumerate() {
            if pair[0] != "#[cfg(test)]" {
                continue;
            }
            let item = pair[1];
            if let Some(name) = item.strip_prefix("mod ").and_then(|m| m.strip_suffix(';')) {
                let dir = if f.file_name().is_some_and(|n| n == "mod.rs") {
                    f.parent().unwrap().to_path_buf()
                } else {
                    f.with_extension("")
                };
                test_files.insert(dir.join(format!("{name}.rs")));
                test_files.insert(dir.join(name).join("mod.rs"));
            } else if !(item.starts_with("mod ") && item.ends_with('{')) {
                panic!(
                    "{}:{}: `#[cfg(test)] {item}`: the architecture scan only understands test modules",
                    f.display(),
                    ln + 2
                );
            }
        }
    }
    let mut graph: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
    for (f, text) in files.iter().zip(&texts) {
        let Some(from) = top_module(&src, f) else {
            continue;
        };
        let entry = graph.entry(from.clone()).or_default();
        let mut test_code =
            f.file_name().is_some_and(|n| n == "tests.rs") || test_files.contains(f);
        let mut cfg_test = false;
        for (ln, line) in text.lines().enumerate() {
            let t = line.trim();
            // `#[cfg(test)] mod NAME;` skips one line (the file is skipped above); `mod NAME {` the rest.
            test_code = test_code || (cfg_test && t.ends_with('{'));
            cfg_test = t == "#[cfg(test)]";
            if test_code || cfg_test {
                continue;
            }
            let code = line.split("//").next().unwrap_or("");
            let mut rest = code;
            while let Some(i) = rest.find("crate::") {
                rest = &rest[i + "crate::".len()..];
                let name: String = rest
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                    .collect();
                if !name.is_empty() && name != from {
                    entry
                        .entry(name)
                        .or_insert_with(|| format!("{}:{}", f.display(), ln + 1));
                }
            }
        }
    }
    graph
}

#[test]
fn no_folder_imports_a_folder_that_imports_it_back() {
    let graph = module_graph();
    assert!(
        graph.len() >= 10,
        "the walk found only {:?}: the test proves nothing",
        graph.keys()
    );
    // Depth-first search for a back edge; report the cycle with one place per edge.
    fn visit(
        m: &str,
        graph: &BTreeMap<String, BTreeMap<String, String>>,
        stack: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(pos) = stack.iter().position(|s| s == m) {
            let mut cycle = stack[pos..].to_vec();
            cycle.push(m.to_string());
            return Some(cycle);
        }
        if done.contains(m) {
            return None;
        }
        stack.push(m.to_string());
        for next in graph.get(m).into_iter().flat_map(|e| e.keys()) {
            if let Some(c) = visit(next, graph, stack, done) {
                return Some(c);
            }
        }
        stack.pop();
        done.insert(m.to_string());
        None
    }
    let mut done = BTreeSet::new();
    for m in graph.keys() {
        if let Some(cycle) = visit(m, &graph, &mut Vec::new(), &mut done) {
            let places: Vec<String> = cycle
                .windows(2)
                .map(|w| format!("{} → {} ({})", w[0], w[1], graph[&w[0]][&w[1]]))
                .collect();
            panic!("import cycle:\n  {}", places.join("\n  "));
        }
    }
}

#[test]
fn the_stages_that_read_a_tree_read_the_model_not_the_preprocessor() {
    let graph = module_graph();
    for reader in [
        "select", "plan", "render", "inspect", "store", "paging", "model", "export",
    ] {
        let edges = graph
            .get(reader)
            .unwrap_or_else(|| panic!("no module {reader}"));
        if let Some(place) = edges.get("preprocess") {
            panic!("{reader} imports the preprocessor at {place}");
        }
    }
    for user in ["select", "render", "inspect", "store"] {
        assert!(
            graph[user].contains_key("model"),
            "{user} does not read the model: {:?}",
            graph[user].keys()
        );
    }
}
