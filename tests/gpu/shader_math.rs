//! The shader's math against its CPU twins (vello's `compare_gpu_cpu`): a compute entry point appended to
//! the renderer's own `shaders/tree.wgsl` source ([`atlastree::render::wgsl::tree::WGSL`], unchanged, so
//! the GPU runs the very `rect_texel`, `level_transform` and `atlas_sample` the fragment shader does, with
//! the real `rects` and `globals` bindings) evaluates them on the grid of `tests/fixtures/shader_math.rs`
//! and the results are compared with:
//!
//! - `RectMap::texel_f32` (the same arithmetic in f32 on the CPU): texel and gradients within 8 f32 ulps
//!   of the larger magnitude (≥ 1 for texels). Vulkan lets `length` (a square root) and division be a few
//!   ulps off and lets the driver fuse a multiply-add; everything else is correctly rounded;
//! - `model::transform::rect_texel` (f64): the tolerance derived in the fixture from f32 precision;
//! - `model::transform::atlas_uv_at_f32` on the GPU's own texel: bit for bit (the level transform is a
//!   power-of-two scale and an exact offset, so the one rounding is the final addition, fused or not), and
//!   the f64 `atlas_uv_at` within 2⁻²⁴ (one rounding of a value in `[0, 1]`).

use atlastree::gpu::GpuContext;
use atlastree::ids::Level;
use atlastree::model::transform::{atlas_uv_at, atlas_uv_at_f32};
use atlastree::render::wgsl::tree::{self, Globals, RectMap};
use bytemuck::{Pod, Zeroable};
use glam::Vec2;
use wgpu::util::DeviceExt;

use crate::harness::GpuTest;
use crate::shader_math_grid::{ATLAS, F64Check, Sample, check_f64, maps, rects, samples};

pub fn tests() -> Vec<GpuTest> {
    vec![GpuTest {
        name: "shader_math::rect_texel_and_level_transform_match_cpu",
        run: rect_texel_and_level_transform_match_cpu,
    }]
}

/// The probe: `tree.wgsl` as the renderer compiles it, plus this entry point and its two buffers (bindings
/// 100 and 101 of group 0, which the renderer leaves free).
const PROBE_WGSL: &str = r#"
struct ProbeIn {
    uv: vec2<f32>,
    ddx: vec2<f32>,
    ddy: vec2<f32>,
    cell: vec2<u32>,
    rect: u32,
    leaf_level: u32,
    level: u32,
    _pad: u32,
}

struct ProbeOut {
    texel: vec2<f32>,
    gx: vec2<f32>,
    gy: vec2<f32>,
    atlas_uv: vec2<f32>,
    atlas_ddx: vec2<f32>,
    atlas_ddy: vec2<f32>,
    level_xf: vec4<f32>,
    mean: vec4<f32>,
    flat: u32,
    mix_mean: f32,
    _p2: u32,
    _p3: u32,
}

@group(0) @binding(100) var<storage, read> probe_in: array<ProbeIn>;
@group(0) @binding(101) var<storage, read_write> probe_out: array<ProbeOut>;

@compute @workgroup_size(64)
fn probe_main(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= arrayLength(&probe_in) {
        return;
    }
    let p = probe_in[i];
    // As vs_main and atlas_sample: the draw packed as the CPU (NodeDraw::pack, layer 0 of array 0) and
    // the vertex stage pack it, the level transform unpacked from it, then the rect map at 1 / 2^(j-K)
    // leaf texels.
    var v: VertexOut;
    v.clip = vec4<f32>(0.0);
    v.uv = p.uv;
    v.draw = atlas_draw(p.level << LEVEL_SHIFT, p.leaf_level, p.cell, p.rect);
    let xf = level_transform(v);
    let r = rect_texel(rects[p.rect], p.uv, p.ddx, p.ddy, 1.0 / xf.x);
    let a = atlas_sample(v, rects[p.rect], p.ddx, p.ddy);
    let flat = select(0u, 1u, r.flat);
    let m = rect_mean(rects[p.rect].mean);
    probe_out[i] = ProbeOut(r.texel, r.gx, r.gy, a.uv, a.ddx, a.ddy, vec4<f32>(xf, 0.0), m, flat, r.mix_mean, 0u, 0u);
}
"#;

#[derive(Copy, Clone, Debug, Pod, Zeroable)]
#[repr(C)]
struct ProbeIn {
    uv: [f32; 2],
    ddx: [f32; 2],
    ddy: [f32; 2],
    cell: [u32; 2],
    rect: u32,
    leaf_level: u32,
    level: u32,
    _pad: u32,
}
const _: () = assert!(size_of::<ProbeIn>() == 48);

#[derive(Copy, Clone, Debug, Default, Pod, Zeroable)]
#[repr(C)]
struct ProbeOut {
    texel: [f32; 2],
    gx: [f32; 2],
    gy: [f32; 2],
    atlas_uv: [f32; 2],
    atlas_ddx: [f32; 2],
    atlas_ddy: [f32; 2],
    level_xf: [f32; 4],
    /// `rect_mean` of the rect: what a flat fragment shows.
    mean: [f32; 4],
    /// `RectSample::flat` and `mix_mean`.
    flat: u32,
    mix_mean: f32,
    _p: [u32; 2],
}
const _: () = assert!(size_of::<ProbeOut>() == 96);

/// Runs the probe over `inputs` with `maps` bound as `rects`.
fn run_probe(
    ctx: &GpuContext,
    maps: &[RectMap],
    inputs: &[ProbeIn],
) -> Result<Vec<ProbeOut>, String> {
    let device = &ctx.device;
    let source = format!("{}\n{PROBE_WGSL}", tree::WGSL);
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("tree.wgsl + probe"),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("probe"),
        layout: None,
        module: &module,
        entry_point: Some("probe_main"),
        compilation_options: wgpu::PipelineCompilationOptions::default(),
        cache: None,
    });
    let globals = Globals {
        view_proj: [[0.0; 4]; 4],
        mode: tree::MODE_TEXTURED,
        atlas_texels: ATLAS as f32,
        _p1: 0,
        _p2: 0,
    };
    let storage = |label, contents: &[u8], usage| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents,
            usage,
        })
    };
    let globals = storage(
        "globals",
        bytemuck::bytes_of(&globals),
        wgpu::BufferUsages::UNIFORM,
    );
    let rects = storage(
        "rects",
        bytemuck::cast_slice(maps),
        wgpu::BufferUsages::STORAGE,
    );
    let input = storage(
        "probe in",
        bytemuck::cast_slice(inputs),
        wgpu::BufferUsages::STORAGE,
    );
    let out_bytes = (inputs.len() * size_of::<ProbeOut>()) as u64;
    let output = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("probe out"),
        size: out_bytes,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let read = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("probe read"),
        size: out_bytes,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("probe"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: tree::binding::GLOBALS,
                resource: globals.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: tree::binding::RECTS,
                resource: rects.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 100,
                resource: input.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 101,
                resource: output.as_entire_binding(),
            },
        ],
    });
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups((inputs.len() as u32).div_ceil(64), 1, 1);
    }
    encoder.copy_buffer_to_buffer(&output, 0, &read, 0, out_bytes);
    ctx.queue.submit([encoder.finish()]);
    let bytes = crate::device::map_read(ctx, &read)?;
    Ok(bytemuck::pod_collect_to_vec(&bytes))
}

/// `|a − b| ≤ 8 ulp(max(|a|, |b|, floor))`, or both NaN (kept for a NaN both sides compute alike; a zero
/// footprint itself now keeps `k = 1`).
fn close(a: f32, b: f32, floor: f32) -> bool {
    if a.is_nan() || b.is_nan() {
        return a.is_nan() && b.is_nan();
    }
    let m = a.abs().max(b.abs()).max(floor);
    (a - b).abs() <= 8.0 * m * f32::EPSILON
}

fn close2(a: Vec2, b: Vec2, floor: f32) -> bool {
    close(a.x, b.x, floor) && close(a.y, b.y, floor)
}

/// One sample's GPU result against the CPU twins; how the f64 comparison went.
fn check_sample(
    s: &Sample,
    map: &RectMap,
    rect: &atlastree::model::AtlasRect,
    out: &ProbeOut,
) -> Result<F64Check, String> {
    let texel = Vec2::from(out.texel);
    let twin = map.sample_f32(s.uv, s.ddx, s.ddy, s.level_texels());
    let (want, wgx, wgy, flat) = (twin.texel, twin.gx, twin.gy, twin.flat);
    let f64_check = check_f64(rect, s, texel)?;
    // The mean a flat fragment shows, as `mean_linear` decodes it: WGSL's `pow` is exp2(y·log2 x), a
    // few ulp on lavapipe and looser elsewhere, so within 10⁻⁵ (a 400th of an 8-bit step).
    let mean = map.mean_linear();
    if !(out.mean.iter().zip(mean)).all(|(&g, w)| (g - w).abs() <= 1e-5) {
        return Err(format!(
            "{s:?}: GPU rect mean {:?}, mean_linear {mean:?}",
            out.mean
        ));
    }
    // Near a branch the GPU may round to the other side than the CPU's f32; such samples are compared with
    // f64 only where it is decisive (never), and the level transform below still is.
    // Near a step of the footprint cap the GPU may take the other side of the step: its gradients are then
    // the twin's scaled by one factor within [1/2, 2] (the cap doubles or halves; k saturates at 1).
    let (gx, gy) = (Vec2::from(out.gx), Vec2::from(out.gy));
    let scaled =
        |f: f32| close2(gx, wgx * f, f32::MIN_POSITIVE) && close2(gy, wgy * f, f32::MIN_POSITIVE);
    let step_factor = {
        let (a, b) = if wgx.length() >= wgy.length() {
            (gx, wgx)
        } else {
            (gy, wgy)
        };
        if b.length() > 0.0 {
            a.length() / b.length()
        } else {
            1.0
        }
    };
    let near_step = f64_check == F64Check::AgreesTexelNearStep;
    let gradients_agree =
        scaled(1.0) || (near_step && (0.5..=2.0).contains(&step_factor) && scaled(step_factor));
    if (f64_check == F64Check::Agrees || near_step) && (out.flat == 1) != flat {
        return Err(format!(
            "{s:?}: GPU flat {}, sample_f32 flat {flat}",
            out.flat
        ));
    }
    if f64_check == F64Check::Agrees && (out.mix_mean - twin.mix_mean).abs() > 1e-5 {
        return Err(format!(
            "{s:?}: GPU mix_mean {}, sample_f32 {}",
            out.mix_mean, twin.mix_mean
        ));
    }
    if (f64_check == F64Check::Agrees || near_step)
        && !(close2(texel, want, 1.0) && gradients_agree)
    {
        return Err(format!(
            "{s:?}: GPU texel {texel} gradients {:?} {:?}, texel_f32 {want} {wgx} {wgy}",
            out.gx, out.gy
        ));
    }
    let (k, j) = (Level(s.leaf_level), Level(s.level));
    let leaf_uv = texel / ATLAS as f32;
    let want_uv = atlas_uv_at_f32(leaf_uv, s.cell, k, j);
    let got_uv = Vec2::from(out.atlas_uv);
    if got_uv.to_array().map(f32::to_bits) != want_uv.to_array().map(f32::to_bits) {
        return Err(format!(
            "{s:?}: GPU atlas uv {got_uv} (level transform {:?}), atlas_uv_at_f32 {want_uv}",
            out.level_xf
        ));
    }
    let exact = atlas_uv_at(leaf_uv.as_dvec2(), s.cell, k, j);
    if (exact - got_uv.as_dvec2()).abs().max_element() > 2f64.powi(-24) {
        return Err(format!("{s:?}: GPU atlas uv {got_uv}, f64 {exact}"));
    }
    // The gradients of the drawn level: the rect's, scaled by 2^(j−K) / atlas side (exact).
    let scale = out.level_xf[0] / ATLAS as f32;
    // Bit for bit (NaN for NaN, see `close`).
    let same = |a: [f32; 2], b: Vec2| {
        a.iter()
            .zip(b.to_array())
            .all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))
    };
    if !same(out.atlas_ddx, Vec2::from(out.gx) * scale)
        || !same(out.atlas_ddy, Vec2::from(out.gy) * scale)
    {
        return Err(format!(
            "{s:?}: atlas gradients {:?} {:?}",
            out.atlas_ddx, out.atlas_ddy
        ));
    }
    Ok(f64_check)
}

/// The WGSL `rect_texel`, `level_transform` and `atlas_sample` against `texel_f32`, the f64 rect map and
/// the f32/f64 level transforms, on every sample of the grid (see the module docs for the tolerances).
fn rect_texel_and_level_transform_match_cpu(ctx: &GpuContext) -> Result<(), String> {
    let rects = rects();
    let maps = maps(&rects);
    let samples = samples(&rects);
    let inputs: Vec<ProbeIn> = samples
        .iter()
        .map(|s| ProbeIn {
            uv: s.uv.to_array(),
            ddx: s.ddx.to_array(),
            ddy: s.ddy.to_array(),
            cell: [s.cell.ix, s.cell.iy],
            rect: s.rect as u32,
            leaf_level: u32::from(s.leaf_level),
            level: u32::from(s.level),
            _pad: 0,
        })
        .collect();
    let outputs = ctx
        .scoped("shader math probe", |_| run_probe(ctx, &maps, &inputs))
        .map_err(|e| e.to_string())??;
    if outputs.len() != samples.len() {
        return Err(format!(
            "{} results for {} samples",
            outputs.len(),
            samples.len()
        ));
    }
    // Every branch is probed: flat fragments (the rect's mean), sampled ones, and samples mixing the mean.
    let flat = outputs.iter().filter(|o| o.flat == 1).count();
    let mixed = (outputs.iter())
        .filter(|o| o.mix_mean > 0.0 && o.mix_mean < 1.0)
        .count();
    if flat == 0 || flat == outputs.len() || mixed == 0 {
        return Err(format!(
            "{flat} of {} samples flat, {mixed} mixing the mean: the grid misses a branch",
            outputs.len()
        ));
    }
    let (mut compared, mut near_step, mut failures) = (0usize, 0usize, Vec::new());
    for (s, out) in samples.iter().zip(&outputs) {
        match check_sample(s, &maps[s.rect], &rects[s.rect], out) {
            Ok(F64Check::Agrees) => compared += 1,
            Ok(F64Check::AgreesTexelNearStep) => {
                compared += 1;
                near_step += 1;
            }
            Ok(F64Check::NearBranch) => {}
            Err(e) => failures.push(e),
        }
    }
    println!(
        "    {} samples, {} compared with texel_f32 and f64 ({} near a step of the footprint cap, whose \
         gradients may be scaled by the step), all with the level transform; {flat} flat, {mixed} mixing the mean",
        samples.len(),
        compared,
        near_step
    );
    if !failures.is_empty() {
        return Err(format!(
            "{} of {} samples disagree:\n{}",
            failures.len(),
            samples.len(),
            failures[..failures.len().min(12)].join("\n")
        ));
    }
    // At least 98%: the rest sit on a branch boundary (see the CPU twin's test).
    if compared * 100 < samples.len() * 98 {
        return Err(format!(
            "only {compared} of {} samples compared",
            samples.len()
        ));
    }
    Ok(())
}
