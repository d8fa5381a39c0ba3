//! Every WGSL file under `shaders/` parses with naga's WGSL front-end and validates with the capabilities the
//! renderer's device has. Runs without a GPU, so shader breakage is caught on any machine.

use std::path::{Path, PathBuf};

use naga::valid::{Capabilities, ValidationFlags, Validator};

/// Shader capabilities the renderer may use: what wgpu grants a device opened by `atlastree::gpu` (the naga
/// defaults). Binding arrays are deliberately absent: lavapipe does not support them, so the renderer uses
/// texture arrays (TAB) instead. Extend this set only together with the features requested in `src/gpu.rs`.
const RENDERER_CAPABILITIES: Capabilities =
    Capabilities::MULTISAMPLED_SHADING.union(Capabilities::CUBE_ARRAY_TEXTURES);

fn shader_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders")
}

/// All `.wgsl` files under `dir`, recursively, sorted.
fn wgsl_files(dir: &Path) -> Result<Vec<PathBuf>, String> {
    let mut found = Vec::new();
    let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    for entry in entries {
        let path = entry.map_err(|e| format!("{}: {e}", dir.display()))?.path();
        if path.is_dir() {
            found.extend(wgsl_files(&path)?);
        } else if path.extension().is_some_and(|e| e == "wgsl") {
            found.push(path);
        }
    }
    found.sort();
    Ok(found)
}

/// Parses and validates one WGSL source; the error is naga's rendered diagnostic with `name` as the path.
fn check_wgsl(name: &str, source: &str) -> Result<(), String> {
    let module = naga::front::wgsl::parse_str(source)
        .map_err(|e| format!("parse error:\n{}", e.emit_to_string_with_path(source, name)))?;
    Validator::new(ValidationFlags::all(), RENDERER_CAPABILITIES)
        .validate(&module)
        .map_err(|e| {
            format!(
                "validation error:\n{}",
                e.emit_to_string_with_path(source, name)
            )
        })?;
    Ok(())
}

#[test]
fn every_shader_parses_and_validates() {
    let dir = shader_dir();
    let files = wgsl_files(&dir).unwrap_or_else(|e| panic!("cannot list shaders: {e}"));
    assert!(
        !files.is_empty(),
        "no .wgsl file under {}: the shader test would pass vacuously",
        dir.display()
    );
    let mut failures = Vec::new();
    for path in &files {
        let name = path
            .strip_prefix(&dir)
            .unwrap_or(path)
            .display()
            .to_string();
        let result = std::fs::read_to_string(path)
            .map_err(|e| format!("read error: {e}"))
            .and_then(|source| check_wgsl(&name, &source));
        if let Err(message) = result {
            failures.push(format!("shaders/{name}: {message}"));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} shaders failed:\n{}",
        failures.len(),
        files.len(),
        failures.join("\n")
    );
}

#[test]
fn the_smoke_shaders_are_found() {
    let files = wgsl_files(&shader_dir()).unwrap_or_else(|e| panic!("cannot list shaders: {e}"));
    let names: Vec<String> = files
        .iter()
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect();
    for expected in ["smoke.wgsl", "smoke_tab.wgsl", "blit.wgsl"] {
        assert!(
            names.iter().any(|n| n == expected),
            "{expected} missing from {names:?}"
        );
    }
}

#[test]
fn the_checker_rejects_syntax_errors() {
    let err = check_wgsl(
        "broken.wgsl",
        "@fragment fn fs() -> @location(0) vec4<f32> { return vec4<f32>(1.0; }",
    )
    .expect_err("a syntax error must not pass");
    assert!(
        err.starts_with("parse error") && err.contains("broken.wgsl"),
        "{err}"
    );
}

#[test]
fn the_checker_rejects_binding_arrays() {
    let source = "
        enable wgpu_binding_array;
        @group(0) @binding(0) var textures: binding_array<texture_2d<f32>, 4>;
        @group(0) @binding(1) var s: sampler;
        @fragment fn fs() -> @location(0) vec4<f32> {
            return textureSample(textures[0], s, vec2<f32>(0.5, 0.5));
        }";
    let err = check_wgsl("binding_array.wgsl", source)
        .expect_err("binding arrays are outside the renderer's capabilities");
    assert!(
        err.starts_with("validation error") && err.contains("TEXTURE_AND_SAMPLER_BINDING_ARRAY"),
        "{err}"
    );
}
