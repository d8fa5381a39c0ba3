//! Alpha trees whose nodes mix MASK and BLEND materials.
//!
//! One scaled leaf can hold a whole track's vegetation (MASK) next to a few BLEND materials; the node is
//! drawn in the blend pipeline (no depth write), so without a depth pre-pass its MASK quads would be
//! ordered by submission instead of depth (on a real track, far corn plants painted over near ones).

use atlastree::camera::Camera;
use atlastree::gpu::GpuContext;
use atlastree::preprocess::{BuildOptions, DMin, NoProgress, build};
use atlastree::render::Mode;
use atlastree::scene::synthetic::SceneBuilder;
use atlastree::scene::{AlphaMode, Scene, UpAxis, Wrap};
use atlastree::select::Source;
use atlastree::store::TreeFile;
use glam::{DVec2, DVec3};

use crate::harness::GpuTest;
use crate::render::{H, W, e, frame, is_sky, psnr_covered, renderer};

pub fn tests() -> Vec<GpuTest> {
    vec![
        GpuTest {
            name: "alpha::mask_occlusion_holds_in_a_node_with_blend",
            run: mask_occlusion_holds_in_a_node_with_blend,
        },
        GpuTest {
            name: "alpha::the_density_pass_covers_what_the_colour_pass_draws",
            run: the_density_pass_covers_what_the_colour_pass_draws,
        },
    ]
}

/// Four rows of MASK "plants" (opaque squares with transparent holes, one colour per row) one behind the
/// other, the near row first in the triangle order (so submission order and depth order disagree); a
/// BLEND pane at the side makes the alpha tree's nodes blend nodes.
fn plants() -> Scene {
    let mut b = SceneBuilder::new(UpAxis::Y);
    let mut materials = Vec::new();
    for (i, rgb) in [
        [40u8, 200, 40],
        [220, 40, 40],
        [40, 40, 220],
        [230, 200, 40],
    ]
    .into_iter()
    .enumerate()
    {
        let img = b.image(&format!("plant {i}"), 64, 64, move |x, y| {
            let hole = (x / 8 + y / 8) % 3 == 0;
            [rgb[0], rgb[1], rgb[2], if hole { 0 } else { 255 }]
        });
        materials.push(b.material(img, [Wrap::Repeat; 2], AlphaMode::Mask { cutoff: 0.5 }));
    }
    let glass = b.image("glass", 16, 16, |_, _| [200, 220, 255, 96]);
    let glass = b.material(glass, [Wrap::ClampToEdge; 2], AlphaMode::Blend);
    // Rows at z = 10, 14, 18, 22 (near first), each 8 m wide squares side by side across x.
    for (row, &m) in materials.iter().enumerate() {
        let z = 10.0 + 4.0 * row as f64;
        for k in -2..=2 {
            let x = f64::from(k) * 6.0 + row as f64 * 1.5;
            b.quad(
                [
                    DVec3::new(x - 4.0, 0.0, z),
                    DVec3::new(x + 4.0, 0.0, z),
                    DVec3::new(x + 4.0, 8.0, z),
                    DVec3::new(x - 4.0, 8.0, z),
                ],
                DVec2::new(0.0, 1.0),
                DVec2::new(1.0, 0.0),
                m,
            );
        }
    }
    b.quad(
        [
            DVec3::new(30.0, 0.0, 12.0),
            DVec3::new(36.0, 0.0, 12.0),
            DVec3::new(36.0, 6.0, 12.0),
            DVec3::new(30.0, 6.0, 12.0),
        ],
        DVec2::ZERO,
        DVec2::ONE,
        glass,
    );
    // An opaque ground so the scene has an opaque tree and a planar extent.
    let ground = b.pattern_image("ground", 32, 9);
    let ground = b.material(ground, [Wrap::Repeat; 2], AlphaMode::Opaque);
    b.quad(
        [
            DVec3::new(-40.0, 0.0, -10.0),
            DVec3::new(40.0, 0.0, -10.0),
            DVec3::new(40.0, 0.0, 60.0),
            DVec3::new(-40.0, 0.0, 60.0),
        ],
        DVec2::ZERO,
        DVec2::splat(10.0),
        ground,
    );
    b.build()
}

/// The plants built at atlas 256 (d_min ratio 8) into `dir`, opened.
fn plants_file(
    dir: &std::path::Path,
) -> Result<(TreeFile, atlastree::preprocess::BuildReport), String> {
    let out = dir.join("plants.atlastree");
    let opts = BuildOptions {
        d_min: DMin::Ratio(8.0),
        atlas_size: 256,
        max_file_bytes: 1 << 30,
        ..BuildOptions::default()
    };
    let report = build(&plants(), &opts, &out, &NoProgress).map_err(e)?;
    Ok((TreeFile::open(&out).map_err(e)?, report))
}

/// A camera `distance` m in front of the first row (z = 10), at `height`, looking level along +z.
fn level_camera(height: f64, distance: f64) -> Camera {
    Camera {
        eye: DVec3::new(2.0, height, 10.0 - distance),
        target: DVec3::new(2.0, height, 16.0),
        up: DVec3::Y,
        fov_x_deg: 60.0,
        aspect: f64::from(W) / f64::from(H),
        near: 0.5,
        far: 1000.0,
    }
}

/// Tree mode against the per-texture reference (each MASK material in the mask pipeline with depth
/// writes): from a view where the rows overlap, with the alpha tree's node drawn from its originals and
/// from its atlas, ≥ 35 dB over the covered pixels (measured: ∞, ∞, 80 dB). Without the depth pre-pass
/// the far rows paint over the near ones (measured: 6.9 dB at 1.5 m); with the node's cutoff instead of
/// each material's, atlas draws blend MASK fringes (21.6 dB at 12 m).
fn mask_occlusion_holds_in_a_node_with_blend(ctx: &GpuContext) -> Result<(), String> {
    let dir = tempfile::tempdir().map_err(e)?;
    let (file, report) = plants_file(dir.path())?;
    if std::env::var_os("ATLASTREE_DEBUG_DIR").is_some() {
        for t in &report.trees {
            println!(
                "  {:?}: {} nodes, {:?}, root md {:.2}, capped rects {}",
                t.kind, t.nodes, t.leaf_reasons, t.root_min_distance, t.capped_rects
            );
        }
    }
    let mut r = renderer(ctx, &file)?;
    let mut lines = Vec::new();
    let mut sources = std::collections::BTreeSet::new();
    for distance in [1.5, 12.0, 40.0] {
        let cam = level_camera(4.0, distance);
        let (_, tree) = frame(&mut r, &file, &cam, Mode::Tree)?;
        let alpha_sources: Vec<Source> = r
            .cuts()
            .get(1)
            .map(|c| c.items.iter().map(|i| i.source).collect())
            .unwrap_or_default();
        sources.extend(alpha_sources.iter().map(|s| format!("{s:?}")));
        let (_, original) = frame(&mut r, &file, &cam, Mode::Original)?;
        let (p, covered) = psnr_covered(&tree, &original);
        if let Some(d) = std::env::var_os("ATLASTREE_DEBUG_DIR") {
            for (name, px) in [("tree", &tree), ("original", &original)] {
                let path = std::path::Path::new(&d).join(format!("alpha-{distance}-{name}.png"));
                image::save_buffer(&path, px, W, H, image::ExtendedColorType::Rgba8).map_err(e)?;
            }
        }
        lines.push(format!(
            "{distance} m: alpha items {alpha_sources:?}, {p:.2} dB over {covered} px"
        ));
        if p < 35.0 || covered < (W * H / 50) as usize {
            return Err(format!("tree vs original: {lines:?}"));
        }
    }
    println!(
        "  MASK rows in a blend node, tree vs original: {}",
        lines.join("; ")
    );
    if sources.len() < 2 {
        return Err(format!(
            "the views must draw the alpha node from atlas and originals, drew {sources:?}"
        ));
    }
    Ok(())
}

/// The density pass (a sweep's covered pixels, magnified shares and histograms) covers exactly the pixels
/// the tree's colour pass draws: the texels a MASK cutoff cuts out of the plants are not covered. It
/// returned before the alpha test, so a cut-out quad of ~30 % opaque texels counted 55,696 covered pixels
/// where 16,958 were drawn (fault hunt, session 38). Looking level through the rows, the holes show sky.
fn the_density_pass_covers_what_the_colour_pass_draws(ctx: &GpuContext) -> Result<(), String> {
    let dir = tempfile::tempdir().map_err(e)?;
    let (file, _) = plants_file(dir.path())?;
    let mut r = renderer(ctx, &file)?;
    for distance in [3.0, 12.0] {
        let cam = level_camera(6.0, distance);
        let (_, colour) = frame(&mut r, &file, &cam, Mode::Tree)?;
        let plan = r.planner.last().ok_or("no plan")?;
        let (_, density) = r.renderer.execute_density(plan).map_err(e)?;
        let drawn: Vec<bool> = colour.chunks_exact(4).map(|p| !is_sky(p)).collect();
        let covered: Vec<bool> = density.pixels.iter().map(Option::is_some).collect();
        let holes = drawn.iter().filter(|d| !**d).count();
        let differ = drawn.iter().zip(&covered).filter(|(d, c)| d != c).count();
        if holes == 0 || differ != 0 {
            return Err(format!(
                "at {distance} m: {differ} pixels covered by the density pass but not drawn, or drawn \
                 but not covered ({holes} sky pixels)"
            ));
        }
    }
    Ok(())
}
