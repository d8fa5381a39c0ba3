//! Every WGSL file under `shaders/` parses with naga's WGSL front-end and validates with the capabilities the
//! renderer's device has, and every shader's Rust twins (`atlastree::render::wgsl`) match it, as naga sees
//! the shader:
//!
//! - structs: every struct the shader shares with the host (the type, or an element or member type, of a
//!   uniform or storage variable) has a Rust twin of the same name, and naga's layout of it (the
//!   `Layouter`'s size, the struct's span, each member's name, offset and size) is the twin's
//!   (`size_of`, `offset_of!`, `size_of_val` of each field; the fields listed cover the whole twin);
//! - bindings: the shader's resource variables and their `@group`/`@binding` are exactly the module's
//!   `binding::ALL`;
//! - overrides: the shader's `override` names are exactly the module's `overrides::ALL`;
//! - constants: the shader's module-scope `const`s are exactly the module's `CONSTS`, with equal values
//!   (f32 bit for bit).
//!
//! Runs without a GPU, so shader breakage and drift between a shader and its twins are caught on any
//! machine.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use atlastree::render::wgsl::{
    Binding, ConstValue, blit, downsample, dummy, naive, smoke_tab, tree,
};
use naga::valid::{Capabilities, ValidationFlags, Validator};

/// Shader capabilities the renderer may use: what wgpu grants a device opened by `atlastree::gpu` (the naga
/// defaults). Binding arrays are deliberately absent: lavapipe does not support them, so the renderer uses
/// texture arrays (TAB) instead. Extend this set only together with the features requested in `src/gpu.rs`.
const RENDERER_CAPABILITIES: Capabilities =
    Capabilities::MULTISAMPLED_SHADING.union(Capabilities::CUBE_ARRAY_TEXTURES);

/// Shaders without a twin module: they share no buffer, binding, override or constant with the host.
const WITHOUT_TWINS: [&str; 1] = ["smoke.wgsl"];

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
fn parse_valid(name: &str, source: &str) -> Result<naga::Module, String> {
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
    Ok(module)
}

fn check_wgsl(name: &str, source: &str) -> Result<(), String> {
    parse_valid(name, source).map(|_| ())
}

// ---------------------------------------------------------------------------------------------------------
// Twins.

/// One field of a Rust twin struct.
struct Field {
    name: &'static str,
    offset: usize,
    size: usize,
}

/// A Rust twin struct, seen through `size_of`, `offset_of!` and `size_of_val`.
struct TwinStruct {
    name: &'static str,
    size: usize,
    fields: Vec<Field>,
}

/// `twin!(module::Type { field, … })`: the layout of a Rust twin (named by the path's last segment), its
/// fields in declaration order.
macro_rules! twin {
    ($t:path { $($f:ident),* $(,)? }) => {{
        let zero: $t = bytemuck::Zeroable::zeroed();
        TwinStruct {
            name: stringify!($t).rsplit("::").next().unwrap_or_default().trim(),
            size: size_of::<$t>(),
            fields: vec![$(Field {
                name: stringify!($f),
                offset: std::mem::offset_of!($t, $f),
                size: std::mem::size_of_val(&zero.$f),
            }),*],
        }
    }};
}

/// A shader and everything its twin module says about it.
struct Twins {
    file: &'static str,
    source: &'static str,
    consts: &'static [(&'static str, ConstValue)],
    overrides: &'static [&'static str],
    bindings: &'static [Binding],
    structs: Vec<TwinStruct>,
}

fn all_twins() -> Vec<Twins> {
    vec![
        Twins {
            file: "tree.wgsl",
            source: tree::WGSL,
            consts: tree::CONSTS,
            overrides: tree::overrides::ALL,
            bindings: tree::binding::ALL,
            structs: vec![
                twin!(tree::Globals {
                    view_proj,
                    mode,
                    atlas_texels,
                    _p1,
                    _p2
                }),
                twin!(tree::NodeDraw {
                    atlas_layer,
                    atlas_array,
                    level,
                    leaf_base,
                    alpha_cutoff,
                    node,
                    tree,
                    draw_bits
                }),
                twin!(tree::LeafInfo {
                    cell,
                    level,
                    first_tam,
                    first_rect,
                    cell_level,
                    _p1,
                    _p2
                }),
                twin!(tree::RectMap {
                    uv_min,
                    texels_per_uv,
                    inner_lo,
                    half_gap,
                    outer_lo,
                    outer_hi,
                    wrap,
                    cutoff,
                    inner_size,
                    mean,
                    point
                }),
                twin!(tree::TamEntry {
                    class_index,
                    layer,
                    wrap,
                    alpha_mode,
                    factor,
                    cutoff,
                    class_size,
                    extent
                }),
            ],
        },
        Twins {
            file: "naive.wgsl",
            source: naive::WGSL,
            consts: naive::CONSTS,
            overrides: naive::overrides::ALL,
            bindings: naive::binding::ALL,
            structs: vec![
                twin!(naive::Globals {
                    view_proj,
                    mode,
                    atlas_texels,
                    _p1,
                    _p2
                }),
                twin!(naive::Material {
                    factor,
                    alpha_mode,
                    cutoff,
                    _p0,
                    _p1
                }),
            ],
        },
        Twins {
            file: "dummy.wgsl",
            source: dummy::WGSL,
            consts: dummy::CONSTS,
            overrides: dummy::overrides::ALL,
            bindings: dummy::binding::ALL,
            structs: vec![
                twin!(dummy::Globals {
                    view_proj,
                    mode,
                    atlas_texels,
                    _p1,
                    _p2
                }),
                twin!(dummy::NodeDraw {
                    atlas_layer,
                    atlas_array,
                    level,
                    leaf_base,
                    alpha_cutoff,
                    node,
                    tree,
                    draw_bits
                }),
            ],
        },
        Twins {
            file: "downsample.wgsl",
            source: downsample::WGSL,
            consts: downsample::CONSTS,
            overrides: downsample::overrides::ALL,
            bindings: downsample::binding::ALL,
            structs: vec![twin!(downsample::Params {
                factor,
                _p0,
                _p1,
                _p2
            })],
        },
        Twins {
            file: "blit.wgsl",
            source: blit::WGSL,
            consts: blit::CONSTS,
            overrides: blit::overrides::ALL,
            bindings: blit::binding::ALL,
            structs: vec![],
        },
        Twins {
            file: "smoke_tab.wgsl",
            source: smoke_tab::WGSL,
            consts: smoke_tab::CONSTS,
            overrides: smoke_tab::overrides::ALL,
            bindings: smoke_tab::binding::ALL,
            structs: vec![twin!(smoke_tab::DrawData {
                layer,
                _pad0,
                _pad1,
                _pad2
            })],
        },
    ]
}

/// Each mismatch between `module` and the twins, as a line.
fn twin_mismatches(module: &naga::Module, twins: &Twins) -> Vec<String> {
    let mut out = Vec::new();
    check_structs(module, &twins.structs, &mut out);
    check_bindings(module, twins.bindings, &mut out);
    check_overrides(module, twins.overrides, &mut out);
    check_consts(module, twins.consts, &mut out);
    out
}

/// The struct types the shader shares with the host: reachable from a uniform or storage variable.
fn host_shared_structs(module: &naga::Module) -> BTreeMap<String, naga::Handle<naga::Type>> {
    let mut found = BTreeMap::new();
    let mut stack: Vec<naga::Handle<naga::Type>> = module
        .global_variables
        .iter()
        .filter(|(_, v)| {
            matches!(
                v.space,
                naga::AddressSpace::Uniform | naga::AddressSpace::Storage { .. }
            )
        })
        .map(|(_, v)| v.ty)
        .collect();
    while let Some(ty) = stack.pop() {
        match &module.types[ty].inner {
            naga::TypeInner::Struct { members, .. } => {
                let name = module.types[ty].name.clone().unwrap_or_default();
                if found.insert(name, ty).is_none() {
                    stack.extend(members.iter().map(|m| m.ty));
                }
            }
            naga::TypeInner::Array { base, .. } | naga::TypeInner::BindingArray { base, .. } => {
                stack.push(*base)
            }
            _ => {}
        }
    }
    found
}

fn check_structs(module: &naga::Module, twins: &[TwinStruct], out: &mut Vec<String>) {
    let mut layouter = naga::proc::Layouter::default();
    if let Err(e) = layouter.update(module.to_ctx()) {
        out.push(format!("naga cannot lay out the types: {e}"));
        return;
    }
    let shared = host_shared_structs(module);
    for name in shared.keys() {
        if !twins.iter().any(|t| t.name == name) {
            out.push(format!(
                "struct {name} is shared with the host but has no Rust twin"
            ));
        }
    }
    for twin in twins {
        let Some(&ty) = shared.get(twin.name) else {
            out.push(format!(
                "Rust twin {} names no struct the shader shares with the host",
                twin.name
            ));
            continue;
        };
        let naga::TypeInner::Struct { members, span } = &module.types[ty].inner else {
            unreachable!("host_shared_structs only returns structs");
        };
        let name = twin.name;
        let listed: usize = twin.fields.iter().map(|f| f.size).sum();
        if listed != twin.size {
            out.push(format!(
                "{name}: the fields listed in this test cover {listed} of the twin's {} bytes",
                twin.size
            ));
        }
        let layout_size = layouter[ty].size as usize;
        if layout_size != twin.size || *span as usize != twin.size {
            out.push(format!(
                "{name}: WGSL size {layout_size} (span {span}), Rust size_of {}",
                twin.size
            ));
        }
        let wgsl_names: Vec<&str> = members
            .iter()
            .map(|m| m.name.as_deref().unwrap_or("?"))
            .collect();
        let rust_names: Vec<&str> = twin.fields.iter().map(|f| f.name).collect();
        if wgsl_names != rust_names {
            out.push(format!(
                "{name}: WGSL members {wgsl_names:?}, Rust fields {rust_names:?}"
            ));
            continue;
        }
        for (m, f) in members.iter().zip(&twin.fields) {
            let size = layouter[m.ty].size as usize;
            if m.offset as usize != f.offset || size != f.size {
                out.push(format!(
                    "{name}.{}: WGSL offset {} size {size}, Rust offset {} size {}",
                    f.name, m.offset, f.offset, f.size
                ));
            }
        }
    }
}

fn check_bindings(module: &naga::Module, bindings: &[Binding], out: &mut Vec<String>) {
    let mut wgsl: Vec<(String, u32, u32)> = module
        .global_variables
        .iter()
        .filter_map(|(_, v)| {
            let b = v.binding.as_ref()?;
            Some((v.name.clone().unwrap_or_default(), b.group, b.binding))
        })
        .collect();
    let mut rust: Vec<(String, u32, u32)> = bindings
        .iter()
        .flat_map(|b| match b.count {
            None => vec![(b.name.to_owned(), b.group, b.binding)],
            Some(n) => (0..n)
                .map(|i| (format!("{}{i}", b.name), b.group, b.binding + i))
                .collect(),
        })
        .collect();
    wgsl.sort();
    rust.sort();
    for w in wgsl.iter().filter(|w| !rust.contains(w)) {
        out.push(format!(
            "WGSL {} @group({}) @binding({}) is not in binding::ALL",
            w.0, w.1, w.2
        ));
    }
    for r in rust.iter().filter(|r| !wgsl.contains(r)) {
        out.push(format!(
            "binding::ALL has {} @group({}) @binding({}), the shader does not",
            r.0, r.1, r.2
        ));
    }
}

fn check_overrides(module: &naga::Module, overrides: &[&str], out: &mut Vec<String>) {
    let wgsl: Vec<String> = module
        .overrides
        .iter()
        .map(|(_, o)| o.name.clone().unwrap_or_default())
        .collect();
    for w in wgsl.iter().filter(|w| !overrides.contains(&w.as_str())) {
        out.push(format!("override {w} is not in overrides::ALL"));
    }
    for r in overrides.iter().filter(|r| !wgsl.iter().any(|w| w == *r)) {
        out.push(format!(
            "overrides::ALL has {r}, the shader has no such override"
        ));
    }
}

/// The value of a module-scope constant, if it is a u32 or f32 literal after naga's constant evaluation.
fn const_value(module: &naga::Module, c: &naga::Constant) -> Option<ConstValue> {
    match module.global_expressions[c.init] {
        naga::Expression::Literal(naga::Literal::U32(v)) => Some(ConstValue::U32(v)),
        naga::Expression::Literal(naga::Literal::F32(v)) => Some(ConstValue::F32(v)),
        _ => None,
    }
}

fn check_consts(module: &naga::Module, consts: &[(&str, ConstValue)], out: &mut Vec<String>) {
    let mut wgsl = BTreeMap::new();
    for (_, c) in module.constants.iter() {
        let name = c.name.clone().unwrap_or_default();
        match const_value(module, c) {
            Some(v) => {
                wgsl.insert(name, v);
            }
            None => out.push(format!(
                "const {name} is not a u32 or f32 literal: {:?}",
                module.global_expressions[c.init]
            )),
        }
    }
    for (name, rust) in consts {
        let same = match (wgsl.get(*name), rust) {
            (Some(ConstValue::U32(a)), ConstValue::U32(b)) => a == b,
            (Some(ConstValue::F32(a)), ConstValue::F32(b)) => a.to_bits() == b.to_bits(),
            (Some(_), _) => false,
            (None, _) => {
                out.push(format!(
                    "Rust const {name} = {rust:?}: the shader has no such const"
                ));
                continue;
            }
        };
        if !same {
            out.push(format!(
                "const {name}: WGSL {:?}, Rust {rust:?}",
                wgsl[*name]
            ));
        }
    }
    for name in wgsl.keys() {
        if !consts.iter().any(|(n, _)| n == name) {
            out.push(format!("WGSL const {name} has no Rust twin in CONSTS"));
        }
    }
}

// ---------------------------------------------------------------------------------------------------------
// Tests.

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
    for expected in [
        "smoke.wgsl",
        "smoke_tab.wgsl",
        "blit.wgsl",
        "dummy.wgsl",
        "downsample.wgsl",
    ] {
        assert!(
            names.iter().any(|n| n == expected),
            "{expected} missing from {names:?}"
        );
    }
}

#[test]
fn every_shader_has_twins_or_is_listed_without() {
    let dir = shader_dir();
    let files = wgsl_files(&dir).unwrap_or_else(|e| panic!("cannot list shaders: {e}"));
    let twins = all_twins();
    for path in &files {
        let name = path.strip_prefix(&dir).unwrap_or(path).to_string_lossy();
        let with = twins.iter().filter(|t| t.file == name).count();
        let without = WITHOUT_TWINS.contains(&name.as_ref());
        assert!(
            with + usize::from(without) == 1,
            "shaders/{name}: {with} twin modules, listed without twins: {without}"
        );
    }
    for t in &twins {
        let on_disk = std::fs::read_to_string(dir.join(t.file))
            .unwrap_or_else(|e| panic!("shaders/{}: {e}", t.file));
        assert_eq!(
            on_disk, t.source,
            "shaders/{}: the twin module's WGSL is not the file",
            t.file
        );
    }
}

#[test]
fn rust_twins_match_the_shaders() {
    let mut failures = Vec::new();
    for t in all_twins() {
        match parse_valid(t.file, t.source) {
            Ok(module) => failures.extend(
                twin_mismatches(&module, &t)
                    .into_iter()
                    .map(|m| format!("shaders/{}: {m}", t.file)),
            ),
            Err(e) => failures.push(format!("shaders/{}: {e}", t.file)),
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The comparison is not vacuous: a twin with a wrong layout, a missing binding, an unknown override and
/// a const of another value are all reported.
#[test]
fn the_twin_check_reports_mismatches() {
    #[derive(Copy, Clone, bytemuck::Pod, bytemuck::Zeroable)]
    #[repr(C)]
    struct Packed {
        a: u32,
        b: [f32; 2],
        _p: u32,
    }
    let source = "
        const CODE: u32 = 2u;
        const LIMIT: f32 = 0.5 / 255.0;
        override FLAG: u32 = 0u;
        struct Packed { a: u32, b: vec2<f32>, _p: u32 }
        @group(0) @binding(0) var<storage, read> data: array<Packed>;
        @group(0) @binding(1) var<uniform> other: vec4<f32>;
        @fragment fn fs() -> @location(0) vec4<f32> {
            return vec4<f32>(data[0].b * LIMIT, f32(FLAG + CODE), other.x);
        }";
    let module = parse_valid("mismatch.wgsl", source).unwrap();
    const BINDINGS: &[Binding] = &[Binding::one("data", 0, 0)];
    let twins = Twins {
        file: "mismatch.wgsl",
        source,
        consts: &[
            ("CODE", ConstValue::U32(3)),
            ("LIMIT", ConstValue::F32(0.5 / 255.0)),
        ],
        overrides: &["FLAG", "OTHER"],
        bindings: BINDINGS,
        structs: vec![twin!(Packed { a, b, _p })],
    };
    let found = twin_mismatches(&module, &twins).join("\n");
    for expected in [
        // vec2<f32> is 8-aligned in WGSL: b at 8, the struct 24 bytes; the Rust twin has b at 4, 16 bytes.
        "Packed: WGSL size 24 (span 24), Rust size_of 16",
        "Packed.b: WGSL offset 8 size 8, Rust offset 4 size 8",
        "WGSL other @group(0) @binding(1) is not in binding::ALL",
        "overrides::ALL has OTHER",
        "const CODE: WGSL U32(2), Rust U32(3)",
    ] {
        assert!(found.contains(expected), "{expected:?} not in:\n{found}");
    }
    assert!(!found.contains("LIMIT"), "{found}");
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
