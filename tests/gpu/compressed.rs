//! Block-compressed trees on the GPU (issue 9).
//!
//! - data/city (both trees, atlas 512, d_min = diagonal / 10) built with `--compress none`, `bc1` and
//!   `bc7`; tree-mode frames along the dive, compressed against uncompressed: PSNR over the covered pixels
//!   ≥ 33 dB for BC1 (BC3 alpha tree) and ≥ 38 dB for BC7, every view.
//! - Where the adapter has `TEXTURE_COMPRESSION_BC` (lavapipe does) the atlas arrays are BC arrays and
//!   nothing is decoded on load (BC1 originals sharing a class with BC3 ones are widened to BC3); the same file loaded as if the adapter lacked BC decodes every
//!   compressed chain on the CPU (counted) and renders the same frames: ≥ 45 dB for BC7 (GPU and CPU BC
//!   decoders may round differently), ≥ 35 dB for BC1. With BC1 the GPU file has two atlas arrays (BC1
//!   opaque, BC3 alpha) and the shader samples them with explicit gradients, while the decoded fallback
//!   has one RGBA8 array sampled with implicit derivatives; the lower floor covers that path difference
//!   (measured: a few alpha-tested pixels of a grazing MASK edge flip, 37.8 dB in the worst view), not
//!   a decoding difference (the CPU-decoded frames are closer to the uncompressed ones than the GPU's).

use atlastree::gpu::{GpuContext, GpuFeatures};
use atlastree::preprocess::{BuildOptions, DMin, NoProgress, build};
use atlastree::render::{FrameLoop, Mode, RendererOptions};
use atlastree::select::{SelectOptions, min_distance_scale};
use atlastree::store::TreeFile;
use atlastree::texfmt::{Compression, TexFormat};
use std::path::{Path, PathBuf};

use crate::harness::GpuTest;
use crate::render::psnr_covered;

pub fn tests() -> Vec<GpuTest> {
    vec![GpuTest {
        name: "compressed::bc_trees_render_like_uncompressed",
        run: bc_trees_render_like_uncompressed,
    }]
}

const W: u32 = 320;
const H: u32 = 240;
const VIEWS: usize = 5;

fn e<E: std::fmt::Display>(x: E) -> String {
    x.to_string()
}

fn build_city(dir: &Path, compress: Compression) -> Result<PathBuf, String> {
    let scene_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/city/scene.gltf");
    let scene = atlastree::scene::import(&scene_path, &Default::default()).map_err(e)?;
    let out = dir.join(format!("city-{compress:?}.atlastree"));
    let opts = BuildOptions {
        d_min: DMin::Ratio(10.0),
        atlas_size: 512,
        max_file_bytes: 1 << 30,
        compress,
        // The paper's tree: every node that does not fit one atlas is split (multi-level).
        leaf_originals_atlases: 0.0,
        ..BuildOptions::default()
    };
    build(&scene, &opts, &out, &NoProgress).map_err(e)?;
    Ok(out)
}

/// Tree-mode frames of the dive views (RGBA8 each), chains decoded on load, the atlas arrays' formats.
/// The frames, the mip chains decoded on load, the atlas arrays' formats and the chains the load uploads
/// (one per atlas block and one per distinct original texture, counted from the tables).
type Frames = (Vec<Vec<u8>>, u64, Vec<TexFormat>, u64);

/// The [`Frames`] of `file` along the dive.
fn frames(ctx: &GpuContext, file: &TreeFile) -> Result<Frames, String> {
    let mut r = FrameLoop::new(ctx, file, RendererOptions::sized(W, H)).map_err(e)?;
    // The dive over the file's ground, as `render` flies it (the bounds-only dive's street-level view of
    // data/city sees nothing).
    let ground = atlastree::camera::Ground::from_tree(file).map_err(e)?;
    let path = atlastree::camera::CameraPath::overview_dive_on(&ground).map_err(e)?;
    let (t0, d) = (path.start(), path.duration());
    let mut out = Vec::new();
    for i in 0..VIEWS {
        let mut cam = path.sample(t0 + d * 0.5 * i as f64 / (VIEWS - 1) as f64);
        cam.aspect = f64::from(W) / f64::from(H);
        let scale = min_distance_scale(
            &file.to_params(),
            &SelectOptions {
                screen_width: W,
                texel_ratio: 1.0,
                fov_x_deg: cam.fov_x_deg,
            },
        )
        .map_err(e)?;
        r.render(&cam, scale, Mode::Tree).map_err(e)?;
        out.push(r.read_frame().map_err(e)?);
    }
    let formats = r
        .renderer
        .resident
        .atlas_arrays
        .iter()
        .map(|a| a.format)
        .collect();
    let resident = &r.renderer.resident;
    let atlases = (file.blocks().iter())
        .filter(|b| b.kind == atlastree::store::format::BLOCK_ATLAS)
        .count();
    let chains = (atlases + resident.uniques.len()) as u64;
    Ok((out, resident.stats.decoded_on_load, formats, chains))
}

/// `ctx` as an adapter without BC support would present it (same device; the loader must decode).
fn without_bc(ctx: &GpuContext) -> GpuContext {
    crate::harness::with_features(
        ctx,
        GpuFeatures {
            texture_compression_bc: false,
            ..ctx.features
        },
    )
}

fn bc_trees_render_like_uncompressed(ctx: &GpuContext) -> Result<(), String> {
    let dir = tempfile::tempdir().map_err(e)?;
    let none = TreeFile::open(&build_city(dir.path(), Compression::None)?).map_err(e)?;
    let (reference, decoded, _, _) = frames(ctx, &none)?;
    if decoded != 0 {
        return Err(format!("uncompressed file decoded {decoded} chains"));
    }
    let mut report = Vec::new();
    for (compress, floor, fallback_floor) in [
        (Compression::Bc1, 33.0, 35.0),
        (Compression::Bc7, 38.0, 45.0),
    ] {
        let file = TreeFile::open(&build_city(dir.path(), compress)?).map_err(e)?;
        let (got, decoded, formats, chains) = frames(ctx, &file)?;
        let bc = ctx.features.texture_compression_bc;
        let stored: Vec<TexFormat> = (0..file.trees())
            .filter_map(|t| file.tree(t).map(|v| v.format()))
            .collect();
        if bc && (decoded != 0 || formats.iter().any(|f| !stored.contains(f))) {
            return Err(format!(
                "{compress:?}: BC adapter but {decoded} chains decoded, arrays {formats:?} (stored {stored:?})"
            ));
        }
        if !bc && (decoded != chains || formats.iter().any(|f| *f != TexFormat::Rgba8)) {
            return Err(format!(
                "{compress:?}: adapter without BC but {decoded} of {chains} chains decoded, arrays {formats:?}"
            ));
        }
        let mut psnrs = Vec::new();
        for (i, (a, b)) in reference.iter().zip(&got).enumerate() {
            let (p, covered) = psnr_covered(a, b);
            if covered < (W * H / 20) as usize {
                psnrs.push(format!("(view {i}: {covered} px)"));
                continue;
            }
            if p < floor {
                return Err(format!(
                    "{compress:?} view {i}: {p:.2} dB < {floor} dB against uncompressed"
                ));
            }
            psnrs.push(format!("{p:.1}"));
        }
        if psnrs.iter().any(|p| p.starts_with('(')) {
            return Err(format!("a view covers under 5 % of the frame: {psnrs:?}"));
        }
        report.push(format!(
            "{compress:?} (arrays {formats:?}): {} dB",
            psnrs.join(", ")
        ));
        if bc {
            // The fallback: the same file on an adapter without BC decodes everything on load.
            let plain = without_bc(ctx);
            let (fallback, decoded, formats, chains) = frames(&plain, &file)?;
            if decoded != chains || formats.iter().any(|f| *f != TexFormat::Rgba8) {
                return Err(format!(
                    "{compress:?} fallback: {decoded} chains decoded of the {chains} uploaded, arrays {formats:?}"
                ));
            }
            let mut worst = f64::INFINITY;
            for (a, b) in got.iter().zip(&fallback) {
                worst = worst.min(psnr_covered(a, b).0);
            }
            if worst < fallback_floor {
                return Err(format!(
                    "{compress:?}: CPU-decoded fallback differs from GPU BC: {worst:.2} dB < {fallback_floor}"
                ));
            }
            report.push(format!(
                "{compress:?} fallback: {decoded} chains decoded on load (all of them), ≥ {worst:.1} dB vs GPU BC"
            ));
        }
    }
    println!("  {}", report.join("; "));
    Ok(())
}
