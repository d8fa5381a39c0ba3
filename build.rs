//! 1. Links the C++ runtime: intel_tex_2's prebuilt ISPC texture-compressor libraries contain a C++ object
//!    (its ASTC helper) that references libstdc++ (libc++ on Apple), which rustc's linker does not add.
//! 2. Embeds the demo's scene: `$OUT_DIR/demo_scene.rs` lists every file under `data/city` with its bytes
//!    (`include_bytes!`), so `atlastree demo` runs wherever the binary is copied (it read the scene from
//!    the folder it was built in: fault hunt, session 29).

use std::path::{Path, PathBuf};

fn main() {
    let os = std::env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    let env = std::env::var("CARGO_CFG_TARGET_ENV").unwrap_or_default();
    match (os.as_str(), env.as_str()) {
        ("macos" | "ios", _) => println!("cargo:rustc-link-lib=c++"),
        ("windows", "msvc") => {}
        _ => println!("cargo:rustc-link-lib=stdc++"),
    }
    println!("cargo:rerun-if-changed=build.rs");
    embed_demo_scene();
}

/// Writes `$OUT_DIR/demo_scene.rs`: `DEMO_SCENE`, `(path under data/city, bytes)` in path order.
fn embed_demo_scene() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap_or_default());
    let root = manifest.join("data/city");
    println!("cargo:rerun-if-changed=data/city");
    let mut files = Vec::new();
    collect(&root, &mut files);
    files.sort();
    let mut src = String::from("pub(crate) const DEMO_SCENE: &[(&str, &[u8])] = &[\n");
    for path in &files {
        let Ok(rel) = path.strip_prefix(&root) else {
            continue;
        };
        let rel = rel.to_string_lossy().replace('\\', "/");
        src.push_str(&format!(
            "    ({rel:?}, include_bytes!({:?})),\n",
            path.to_string_lossy()
        ));
    }
    src.push_str("];\n");
    let out = PathBuf::from(std::env::var("OUT_DIR").unwrap_or_default()).join("demo_scene.rs");
    if let Err(e) = std::fs::write(&out, src) {
        println!("cargo:warning=writing {}: {e}", out.display());
    }
}

/// Every regular file under `dir`, recursively.
fn collect(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        match entry.file_type() {
            Ok(t) if t.is_dir() => collect(&path, out),
            Ok(t) if t.is_file() => out.push(path),
            _ => {}
        }
    }
}
