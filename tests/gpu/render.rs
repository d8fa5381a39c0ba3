//! The texture-array-batched renderer end to end: build a small tree, render views in every mode, compare.
//!
//! - tree vs original textures (same view, texel ratio 1): PSNR ≥ 35 dB over the covered pixels, root-atlas
//!   views included;
//! - tree mode: one multi-draw call per non-empty pipeline and one bind group, however many nodes are drawn;
//! - a scene translated by (4.5e6, 0, 5.5e6) renders as at the origin: PSNR ≥ 50 dB;
//! - tree-levels on a dive view shows ≥ 2 level colours.
//!
//! Frames are 320×240: lavapipe's cost is per triangle and per pixel.

use atlastree::camera::{Camera, CameraPath};
use atlastree::gpu::GpuContext;
use atlastree::preprocess::{BuildOptions, DMin, NoProgress, build};
use atlastree::render::batch::{Group, Pass};
use atlastree::render::{FrameLoop, FrameStats, Mode, RendererOptions};
use atlastree::scene::Scene;
use atlastree::select::{SelectOptions, Source, min_distance_scale};
use atlastree::store::TreeFile;
use glam::DVec3;
use std::path::{Path, PathBuf};

use crate::harness::GpuTest;

pub fn tests() -> Vec<GpuTest> {
    vec![
        GpuTest {
            name: "render::tree_matches_original_textures",
            run: tree_matches_original_textures,
        },
        GpuTest {
            name: "render::tree_mode_one_multi_draw_per_pipeline",
            run: tree_mode_one_multi_draw_per_pipeline,
        },
        GpuTest {
            name: "render::translated_scene_renders_the_same",
            run: translated_scene_renders_the_same,
        },
        GpuTest {
            name: "render::tree_levels_shows_several_levels",
            run: tree_levels_shows_several_levels,
        },
        GpuTest {
            name: "render::anisotropy_reaches_the_samplers",
            run: anisotropy_reaches_the_samplers,
        },
    ]
}

pub(crate) const W: u32 = 320;
pub(crate) const H: u32 = 240;

pub(crate) fn e<E: std::fmt::Display>(x: E) -> String {
    x.to_string()
}

/// data/city (with alpha materials: both trees, all three pipelines) at atlas 512, d_min = diagonal / 10,
/// every node that does not fit split (the paper's tree): 13 nodes, depth 2 (opaque tree).
pub(crate) fn build_city(dir: &Path) -> Result<PathBuf, String> {
    let scene_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/city/scene.gltf");
    let scene = atlastree::scene::import(&scene_path, &Default::default()).map_err(e)?;
    build_scene(&scene, dir, "city.atlastree", DMin::Ratio(10.0), 512)
}

/// [`build_city`] built once per test run into cargo's test scratch directory (the build is
/// deterministic; tests only read the file).
pub(crate) fn city() -> Result<PathBuf, String> {
    static BUILT: std::sync::OnceLock<Result<PathBuf, String>> = std::sync::OnceLock::new();
    BUILT
        .get_or_init(|| build_city(Path::new(env!("CARGO_TARGET_TMPDIR"))))
        .clone()
}

/// [`build_city_deep`] built once per test run into cargo's test scratch directory (the build is
/// deterministic; tests only read the file).
pub(crate) fn city_deep() -> Result<PathBuf, String> {
    static BUILT: std::sync::OnceLock<Result<PathBuf, String>> = std::sync::OnceLock::new();
    BUILT
        .get_or_init(|| build_city_deep(Path::new(env!("CARGO_TARGET_TMPDIR"))))
        .clone()
}

/// The same at d_min = diagonal / 20: 106 nodes, depth 4, 187 blocks (paging, level colours).
pub(crate) fn build_city_deep(dir: &Path) -> Result<PathBuf, String> {
    let scene_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/city/scene.gltf");
    let scene = atlastree::scene::import(&scene_path, &Default::default()).map_err(e)?;
    build_scene(&scene, dir, "city-deep.atlastree", DMin::Ratio(20.0), 512)
}

fn build_scene(
    scene: &Scene,
    dir: &Path,
    name: &str,
    d_min: DMin,
    atlas: u32,
) -> Result<PathBuf, String> {
    let out = dir.join(name);
    let opts = BuildOptions {
        d_min,
        atlas_size: atlas,
        max_file_bytes: 1 << 30,
        // The paper's tree: every node that does not fit one atlas is split (multi-level).
        leaf_originals_atlases: 0.0,
        ..BuildOptions::default()
    };
    build(scene, &opts, &out, &NoProgress).map_err(e)?;
    Ok(out)
}

pub(crate) fn bounds(file: &TreeFile) -> Result<(DVec3, DVec3), String> {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for t in 0..file.trees() {
        let root = file
            .tree(t)
            .and_then(|v| v.nodes.first().copied())
            .ok_or("empty tree")?;
        lo = lo.min(DVec3::from_array(root.bounds_min));
        hi = hi.max(DVec3::from_array(root.bounds_max));
    }
    Ok((lo, hi))
}

pub(crate) fn scale_for(file: &TreeFile, cam: &Camera) -> Result<f64, String> {
    min_distance_scale(
        &file.to_params(),
        &SelectOptions {
            screen_width: W,
            texel_ratio: 1.0,
            fov_x_deg: cam.fov_x_deg,
        },
    )
    .map_err(e)
}

pub(crate) fn renderer<'f>(
    ctx: &'f GpuContext,
    file: &'f TreeFile,
) -> Result<FrameLoop<'f>, String> {
    renderer_with(ctx, file, atlastree::render::RendererOptions::ANISOTROPY)
}

/// A W×H renderer with sampler anisotropy `anisotropy` ([`RendererOptions::AUTO`] for the device's).
pub(crate) fn renderer_with<'f>(
    ctx: &'f GpuContext,
    file: &'f TreeFile,
    anisotropy: u16,
) -> Result<FrameLoop<'f>, String> {
    FrameLoop::new(
        ctx,
        file,
        RendererOptions {
            anisotropy,
            ..RendererOptions::sized(W, H)
        },
    )
    .map_err(e)
}

pub(crate) fn frame(
    r: &mut FrameLoop<'_>,
    file: &TreeFile,
    cam: &Camera,
    mode: Mode,
) -> Result<(FrameStats, Vec<u8>), String> {
    let s = r.render(cam, scale_for(file, cam)?, mode).map_err(e)?;
    Ok((s, r.read_frame().map_err(e)?))
}

/// The overview-dive path sampled at `n` times, aspect W/H.
pub(crate) fn dive_cameras(file: &TreeFile, n: usize) -> Result<Vec<Camera>, String> {
    let (lo, hi) = bounds(file)?;
    let path = CameraPath::overview_dive(lo, hi, file.to_params().up).map_err(e)?;
    let (t0, d) = (path.start(), path.duration());
    Ok((0..n)
        .map(|i| {
            let mut c = path.sample(t0 + d * 0.5 * i as f64 / (n - 1).max(1) as f64);
            c.aspect = f64::from(W) / f64::from(H);
            c
        })
        .collect())
}

/// sRGB bytes of the clear colour.
fn sky() -> [u8; 3] {
    atlastree::render::sky_srgb8()
}

pub(crate) fn is_sky(px: &[u8]) -> bool {
    let s = sky();
    (0..3).all(|c| px[c].abs_diff(s[c]) <= 1)
}

/// PSNR (dB) of the RGB channels over the pixels that are not background in at least one image, and the
/// number of such pixels ([`atlastree::texfmt::psnr`]: identical covered pixels give the 99 dB cap).
pub(crate) fn psnr_covered(a: &[u8], b: &[u8]) -> (f64, usize) {
    let (mut sse, mut n) = (0u64, 0usize);
    for (pa, pb) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        if is_sky(pa) && is_sky(pb) {
            continue;
        }
        n += 1;
        sse += (0..3)
            .map(|c| u64::from(pa[c].abs_diff(pb[c])).pow(2))
            .sum::<u64>();
    }
    (atlastree::texfmt::psnr(sse, 3 * n as u64), n)
}

/// Tree frame (atlases where they suffice) against the frame drawn with every original texture bound
/// separately, on views along the dive. At texel ratio 1 the atlases hold the texture resolution the
/// screen needs, so every view that draws atlases must agree to ≥ 35 dB over the covered pixels — the
/// overview drawn with the **root** atlas too.
///
/// The root views are the hard ones: the camera is beyond the root's min_distance, the sampler picks
/// coarser mips of the root atlas, and the border (halved at every level up) is what keeps neighbouring
/// areas apart there. With repeats wrapped in the shader every period boundary of a repeated texture is a
/// seam of its rect: the views must show seams drawn with atlases at two levels at least (counted from the
/// cut: items whose triangles' UVs span more than their rect's period), at sampler anisotropy 1 and 16.
fn tree_matches_original_textures(ctx: &GpuContext) -> Result<(), String> {
    let file = TreeFile::open(&city()?).map_err(e)?;
    let mut failures = Vec::new();
    let mut lines = Vec::new();
    let software = ctx.info.is_software();
    for anisotropy in [1u16, 16] {
        let mut r = renderer_with(ctx, &file, anisotropy)?;
        // A software rasteriser's anisotropic path may ignore explicit gradients (lavapipe: constant
        // 0.2-UV gradients render 15.8 dB apart at anisotropy 1 and 16), so the floor at 16 is asserted on
        // hardware adapters only; on software the measured numbers are printed loudly.
        let mut own = Vec::new();
        let sink = if anisotropy > 1 && software {
            &mut own
        } else {
            &mut failures
        };
        let (report, seam_levels) = compare_views(&mut r, &file, sink)?;
        if !own.is_empty() {
            println!(
                "  NOT ASSERTED on software adapter {} at anisotropy {anisotropy} (driver ignores explicit \
                 gradients there): {own:?}",
                ctx.info
            );
        }
        lines.push(format!(
            "anisotropy {anisotropy}: seams drawn with atlases at levels {seam_levels:?}; {}",
            report.join("; ")
        ));
        if seam_levels.len() < 2 {
            failures.push(format!(
                "anisotropy {anisotropy}: seams drawn with atlases at levels {seam_levels:?}, want ≥ 2"
            ));
        }
    }
    println!(
        "  tree vs original PSNR per view:\n    {}",
        lines.join("\n    ")
    );
    if !failures.is_empty() {
        return Err(format!("{failures:?}; all views: {lines:?}"));
    }
    Ok(())
}

/// Levels of the atlas items of `r`'s last cut whose triangles cross a wrap seam: some triangle of the
/// item's subtree spans more UV than its rect holds on a REPEAT axis.
fn seam_levels(r: &FrameLoop<'_>, file: &TreeFile) -> std::collections::BTreeSet<u8> {
    use atlastree::model::RectWrap;
    let mut levels = std::collections::BTreeSet::new();
    for (t, cut) in r.cuts().iter().enumerate() {
        let Some(view) = file.tree(t) else { continue };
        for item in cut.items.iter().filter(|i| i.source == Source::Atlas) {
            let first = item.first_index as usize;
            let end = first + item.index_count as usize;
            let crosses = view.leaves.iter().any(|leaf| {
                let (lf, ln) = (leaf.first_index as usize, leaf.index_count as usize);
                if lf < first || lf + ln > end {
                    return false;
                }
                let rects = view.leaf_rects(leaf);
                view.indices[lf..lf + ln].chunks_exact(3).any(|tri| {
                    let v = [tri[0], tri[1], tri[2]].map(|i| view.vertices[i as usize]);
                    let rect = rects[v[0].rect as usize].decode();
                    (0..2).any(|k| {
                        let lo = v.iter().map(|v| v.orig_uv[k]).fold(f32::INFINITY, f32::min);
                        let hi = v
                            .iter()
                            .map(|v| v.orig_uv[k])
                            .fold(f32::NEG_INFINITY, f32::max);
                        rect.wrap[k] == RectWrap::Repeat
                            && f64::from(hi - lo) > rect.uv_max[k] - rect.uv_min[k] + 1e-6
                    })
                })
            });
            if crosses {
                levels.insert(item.level);
            }
        }
    }
    levels
}

/// Tree against original frames on the dive views; failures appended; returns the per-view lines and the
/// levels at which wrap seams were drawn with atlases.
fn compare_views(
    r: &mut FrameLoop<'_>,
    file: &TreeFile,
    failures: &mut Vec<String>,
) -> Result<(Vec<String>, std::collections::BTreeSet<u8>), String> {
    let (mut below_root, mut root_views, mut report) = (0, 0, Vec::new());
    let mut seams = std::collections::BTreeSet::new();
    for cam in dive_cameras(file, 8)? {
        let r = &mut *r;
        let (ts, tree) = frame(r, file, &cam, Mode::Tree)?;
        seams.extend(seam_levels(r, file));
        let items: Vec<_> = r.cuts().iter().flat_map(|c| &c.items).copied().collect();
        let atlas_items = items.iter().filter(|i| i.source == Source::Atlas).count();
        let root_atlas = items
            .iter()
            .any(|i| i.source == Source::Atlas && i.level == 0);
        let (os, orig) = frame(r, file, &cam, Mode::Original)?;
        if ts.triangles != os.triangles {
            return Err(format!(
                "tree draws {} triangles, original {}",
                ts.triangles, os.triangles
            ));
        }
        let (psnr, covered) = psnr_covered(&tree, &orig);
        let line = format!(
            "{psnr:.2} dB over {covered} px ({atlas_items} atlas items{})",
            if root_atlas { ", root" } else { "" }
        );
        if covered < (W * H / 20) as usize || atlas_items == 0 {
            report.push(line);
            continue;
        }
        if psnr < 35.0 {
            failures.push(format!("{line} < 35 dB"));
        }
        if root_atlas {
            root_views += 1;
        } else {
            below_root += 1;
        }
        report.push(line);
    }
    if below_root == 0 || root_views == 0 {
        failures.push(format!(
            "need views with the root atlas and below it, got {root_views} and {below_root}"
        ));
    }
    Ok((report, seams))
}

/// Tree mode: one bind group and one multi-draw call per non-empty pipeline (pass × atlas/originals, at most
/// 6), for cuts of very different sizes; one indirect record per selected node (two for a blend node:
/// depth pre-pass and blend). Original mode: one bind
/// group and one draw per (leaf, original texture).
fn tree_mode_one_multi_draw_per_pipeline(ctx: &GpuContext) -> Result<(), String> {
    let file = TreeFile::open(&city()?).map_err(e)?;
    let mut r = renderer(ctx, &file)?;
    let mut drawn = Vec::new();
    // Texel ratios 1, 4 and 16 on the same views: cuts from the root alone to dozens of leaves.
    let views: Vec<(Camera, f64)> = dive_cameras(&file, 4)?
        .into_iter()
        .flat_map(|c| [1.0, 4.0, 16.0].map(|k| (c, k)))
        .collect();
    for (cam, ratio) in views {
        let scale = scale_for(&file, &cam)? * ratio;
        let s = r.render(&cam, scale, Mode::Tree).map_err(e)?;
        let passes = r
            .renderer
            .batch()
            .group_ranges
            .iter()
            .filter(|(_, n)| *n > 0)
            .count() as u32;
        if s.bind_group_changes != 1 || s.draw_calls != passes || passes == 0 || passes > 6 {
            return Err(format!(
                "{} nodes drawn: {} bind groups, {} draw calls for {passes} non-empty pipeline groups",
                s.plan.nodes_drawn, s.bind_group_changes, s.draw_calls
            ));
        }
        // A blend node is drawn twice: its depth pre-pass in the mask pipeline, then blended.
        let blend_records: u32 = [
            Group::new(Pass::Blend, false),
            Group::new(Pass::Blend, true),
        ]
        .iter()
        .map(|g| r.renderer.batch().group_ranges[g.index()].1)
        .sum();
        if s.indirect_records != s.plan.nodes_drawn + blend_records {
            return Err(format!(
                "{} indirect records for {} selected nodes ({blend_records} of them blend nodes)",
                s.indirect_records, s.plan.nodes_drawn
            ));
        }
        drawn.push(s.plan.nodes_drawn);
        let o = r.render(&cam, scale, Mode::Original).map_err(e)?;
        if o.draw_calls < s.draw_calls || o.bind_group_changes != o.draw_calls + 1 {
            return Err(format!(
                "original mode: {} draws, {} bind groups",
                o.draw_calls, o.bind_group_changes
            ));
        }
    }
    let (min, max) = (
        drawn.iter().min().copied().unwrap_or(0),
        drawn.iter().max().copied().unwrap_or(0),
    );
    println!("  nodes drawn per view: {drawn:?}");
    if max < min + 10 {
        return Err(format!(
            "the views do not vary the cut enough to test batching: {drawn:?}"
        ));
    }
    Ok(())
}

/// `RendererOptions::anisotropy` reaches every sampler: on street-level views (grazing angles) of the
/// tree and original modes, isotropic filtering (1) gives other pixels than 16× where the device filters
/// anisotropically (identical ones where it cannot), yet stays a faithful image of the same view
/// (≥ 25 dB against 16× over the covered pixels: only the blur at grazing angles differs).
fn anisotropy_reaches_the_samplers(ctx: &GpuContext) -> Result<(), String> {
    let file = TreeFile::open(&city()?).map_err(e)?;
    let (lo, hi) = bounds(&file)?;
    let path = CameraPath::street(lo, hi, file.to_params().up).map_err(e)?;
    let make = |anisotropy| {
        FrameLoop::new(
            ctx,
            &file,
            RendererOptions {
                anisotropy,
                ..RendererOptions::sized(W, H)
            },
        )
        .map_err(e)
    };
    let (mut iso, mut aniso) = (make(1)?, make(16)?);
    let mut report = Vec::new();
    // Frames that differ between 1× and 16×, per mode (tree samplers, naive samplers).
    let mut differing = [0usize; 2];
    for i in 0..4 {
        let mut cam = path.sample(path.start() + path.duration() * (0.1 + 0.2 * f64::from(i)));
        cam.aspect = f64::from(W) / f64::from(H);
        for (m, mode) in [Mode::Tree, Mode::Original].into_iter().enumerate() {
            let (_, a) = frame(&mut iso, &file, &cam, mode)?;
            let (_, b) = frame(&mut aniso, &file, &cam, mode)?;
            let (psnr, covered) = psnr_covered(&a, &b);
            report.push(format!("{}: {psnr:.1} dB over {covered} px", mode.name()));
            if covered > 0 && psnr.is_finite() {
                differing[m] += 1;
            }
            if covered > 0 && psnr < 25.0 {
                return Err(format!("anisotropy 1 vs 16 only {psnr:.1} dB: {report:?}"));
            }
        }
    }
    println!(
        "  anisotropy 1 vs 16 per street view: {}",
        report.join("; ")
    );
    match (ctx.features.anisotropic_filtering, differing) {
        (true, [t, o]) if t == 0 || o == 0 => Err(format!(
            "anisotropy 1 and 16 render identically in a mode (tree {t}, original {o} frames differ): {report:?}"
        )),
        (false, [t, o]) if t + o > 0 => Err(format!(
            "no anisotropic filtering, yet {} frames differ: {report:?}",
            t + o
        )),
        _ => Ok(()),
    }
}

/// small_city at the origin and translated to UTM-size coordinates, same camera relative to the scene: the
/// frames agree to ≥ 50 dB (positions are camera-relative per leaf, computed in f64).
fn translated_scene_renders_the_same(ctx: &GpuContext) -> Result<(), String> {
    let by = DVec3::new(4.5e6, 0.0, 5.5e6);
    let dir = tempfile::tempdir().map_err(e)?;
    let base = atlastree::scene::synthetic::small_city(3, 64);
    let mut moved = base.clone();
    for v in &mut moved.vertices {
        v.pos += by;
    }
    let opts = (DMin::Metres(40.0), 256);
    let fa = TreeFile::open(&build_scene(&base, dir.path(), "a", opts.0, opts.1)?).map_err(e)?;
    let fb = TreeFile::open(&build_scene(&moved, dir.path(), "b", opts.0, opts.1)?).map_err(e)?;
    let mut ra = renderer(ctx, &fa)?;
    let mut rb = renderer(ctx, &fb)?;
    let mut results = Vec::new();
    for cam in dive_cameras(&fa, 3)? {
        let mut moved_cam = cam;
        moved_cam.eye += by;
        moved_cam.target += by;
        let (sa, a) = frame(&mut ra, &fa, &cam, Mode::Tree)?;
        let (sb, b) = frame(&mut rb, &fb, &moved_cam, Mode::Tree)?;
        let (psnr, covered) = psnr_covered(&a, &b);
        results.push(format!("{psnr:.1} dB over {covered} px"));
        if sa.plan.nodes_drawn != sb.plan.nodes_drawn || psnr < 50.0 || covered == 0 {
            return Err(format!(
                "translated frame differs: {} vs {} nodes, {results:?}",
                sa.plan.nodes_drawn, sb.plan.nodes_drawn
            ));
        }
    }
    println!("  translated vs origin: {}", results.join("; "));
    Ok(())
}

/// Tree-levels on the dive: some view shows at least two different level colours, and every covered pixel
/// is a level colour or white (original textures).
fn tree_levels_shows_several_levels(ctx: &GpuContext) -> Result<(), String> {
    let file = TreeFile::open(&city_deep()?).map_err(e)?;
    let mut r = renderer(ctx, &file)?;
    // The shader's level colours as a frame holds them (the view's overlay draws the same, checked
    // against the shader's palette).
    let palette: Vec<[u8; 3]> = (0..8)
        .map(|l| {
            let [r, g, b, _] = atlastree::view::overlay::level_colour(l).to_array();
            [r, g, b]
        })
        .collect();
    let mut best = 0;
    let mut seen_per_view = Vec::new();
    for cam in dive_cameras(&file, 12)? {
        let (_, img) = frame(&mut r, &file, &cam, Mode::TreeLevels)?;
        let mut counts = [0usize; 9];
        let mut other = 0usize;
        for px in img.chunks_exact(4) {
            if is_sky(px) {
                continue;
            }
            let near = |c: &[u8; 3]| (0..3).all(|k| px[k].abs_diff(c[k]) <= 2);
            match palette.iter().position(near) {
                Some(i) => counts[i] += 1,
                None if near(&[255, 255, 255]) => counts[8] += 1,
                None => other += 1,
            }
        }
        if other > 0 {
            return Err(format!(
                "{other} pixels are neither a level colour nor white"
            ));
        }
        // A level counts when it covers at least 20 pixels (not a stray edge).
        let levels = counts[..8].iter().filter(|&&n| n >= 20).count();
        best = best.max(levels);
        seen_per_view.push(counts);
    }
    println!("  level colour pixel counts per view: {seen_per_view:?}");
    if best < 2 {
        return Err(format!(
            "no dive view shows two level colours: {seen_per_view:?}"
        ));
    }
    Ok(())
}
