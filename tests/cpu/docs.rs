//! Citations of the design document: every mention of it in `src/`, `shaders/` and `tests/` is
//! `docs/DESIGN.md "Section"`, the file exists, and each cited section is one of its headings — the
//! heading's whole text, or its short name before the first `:` (`"Repeats"` for `## Repeats: one period
//! per rect, wrapped in the shader`). Citations may wrap over comment lines.

use std::path::{Path, PathBuf};

const DOC: &str = "docs/DESIGN.md";

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let p = entry.unwrap().path();
        if p.is_dir() {
            files(&p, out);
        } else if p
            .extension()
            .is_some_and(|e| e == "rs" || e == "wgsl" || e == "py" || e == "md")
        {
            out.push(p);
        }
    }
}

/// `text` with comment leaders (`//!`, `///`, `//`, `*`, `#`) stripped from every line and the lines
/// joined by one space, so a citation reads the same however it wraps.
fn flatten(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for line in text.lines() {
        let t = line.trim_start();
        let t = ["//!", "///", "//", "*", "#"]
            .iter()
            .find_map(|l| t.strip_prefix(l))
            .unwrap_or(t);
        out.push_str(t.trim());
        out.push(' ');
    }
    out
}

/// The headings of the design document (`#`-lines, without the hashes).
fn headings(doc: &str) -> Vec<String> {
    doc.lines()
        .filter(|l| l.starts_with('#'))
        .map(|l| l.trim_start_matches('#').trim().to_string())
        .collect()
}

/// Whether `section` names a heading: its whole text or its short name (before the first `:`).
fn names_heading(section: &str, headings: &[String]) -> bool {
    headings
        .iter()
        .any(|h| h == section || h.split(':').next().is_some_and(|s| s.trim() == section))
}

/// Every citation: (file, cited section or the problem).
fn citations() -> Vec<(PathBuf, Result<String, String>)> {
    let me = root().join("tests/cpu/docs.rs");
    let mut all = Vec::new();
    for dir in ["src", "shaders", "tests"] {
        files(&root().join(dir), &mut all);
    }
    all.sort();
    let needle = "DESIGN";
    let mut out = Vec::new();
    for f in all.into_iter().filter(|f| *f != me) {
        let text = flatten(&std::fs::read_to_string(&f).unwrap());
        for (at, _) in text.match_indices(needle) {
            let before = &text[..at];
            let after = &text[at + needle.len()..];
            let cited = if !before.ends_with("docs/") || !after.starts_with(".md") {
                let ctx: String = text[at.saturating_sub(20)..].chars().take(60).collect();
                Err(format!("not cited as {DOC}: …{ctx}…"))
            } else {
                let rest = after[".md".len()..].trim_start();
                match rest.strip_prefix('"').and_then(|r| r.split_once('"')) {
                    Some((section, _)) => {
                        Ok(section.split_whitespace().collect::<Vec<_>>().join(" "))
                    }
                    None => {
                        let ctx: String = rest.chars().take(40).collect();
                        Err(format!("{DOC} cited without a \"Section\": …{ctx}…"))
                    }
                }
            };
            out.push((f.clone(), cited));
        }
    }
    out
}

#[test]
fn design_citations_name_sections_that_exist() {
    let doc = std::fs::read_to_string(root().join(DOC)).expect("docs/DESIGN.md exists");
    let heads = headings(&doc);
    let cites = citations();
    assert!(
        cites.len() >= 20,
        "the scan found only {} citations: is it still reading the sources?",
        cites.len()
    );
    let bad: Vec<String> = cites
        .iter()
        .filter_map(|(f, c)| {
            let f = f.strip_prefix(root()).unwrap_or(f).display();
            match c {
                Ok(s) if names_heading(s, &heads) => None,
                Ok(s) => Some(format!("{f}: section \"{s}\" is not a heading of {DOC}")),
                Err(e) => Some(format!("{f}: {e}")),
            }
        })
        .collect();
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

#[test]
fn the_citation_rule_reads_wrapped_and_short_names() {
    let heads = vec![
        "Precision".to_string(),
        "Repeats: one period per rect, wrapped in the shader".to_string(),
    ];
    assert!(names_heading("Precision", &heads));
    assert!(names_heading("Repeats", &heads));
    assert!(names_heading(
        "Repeats: one period per rect, wrapped in the shader",
        &heads
    ));
    assert!(!names_heading("Repeats: one period per rect", &heads));
    assert!(!names_heading("Precisions", &heads));
    let t = flatten("//! see docs/DESIGN.md \"Repeats: one period\n//! per rect\" and\n/// more");
    assert_eq!(
        t,
        "see docs/DESIGN.md \"Repeats: one period per rect\" and more "
    );
}

/// Every environment variable `src/` reads (`env::var("…")`, `var_os("…")`) is listed under
/// `atlastree --help` (they were documented only in the source; session 38), but glibc's own
/// `MALLOC_ARENA_MAX`, which the binary only honours.
#[test]
fn every_environment_variable_read_is_in_the_help() {
    let mut sources = Vec::new();
    files(&root().join("src"), &mut sources);
    let mut names = std::collections::BTreeSet::new();
    for p in sources
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "rs"))
    {
        let text = std::fs::read_to_string(p).unwrap();
        for call in ["var(\"", "var_os(\"", "from_env(\""] {
            for (at, _) in text.match_indices(call) {
                let rest = &text[at + call.len()..];
                let name = &rest[..rest.find('"').unwrap()];
                if !name.is_empty() && name.bytes().all(|b| b.is_ascii_uppercase() || b == b'_') {
                    names.insert(name.to_string());
                }
            }
        }
    }
    assert!(names.contains("RAYON_NUM_THREADS"), "{names:?}");
    // Read by name from a list, a closure or a library: the log filter's, wgpu's and `build --shard
    // auto`'s.
    names.extend(
        [
            "ATLASTREE_LOG",
            "RUST_LOG",
            "WGPU_BACKEND",
            "SLURM_ARRAY_TASK_ID",
            "SLURM_ARRAY_TASK_COUNT",
            "JOB_COMPLETION_INDEX",
            "AWS_BATCH_JOB_ARRAY_INDEX",
            "ATLASTREE_SHARD_COUNT",
        ]
        .map(String::from),
    );
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_atlastree"))
        .arg("--help")
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&o.stdout);
    for name in names.iter().filter(|n| *n != "MALLOC_ARENA_MAX") {
        assert!(
            help.contains(name.as_str()),
            "{name} is read but not in `atlastree --help`"
        );
    }
}
