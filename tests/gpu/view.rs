//! The renderer hooks the viewer (`atlastree view`) relies on:
//!
//! - `Renderer::freeze_selection`: frames of another camera keep the frozen camera's cut exactly (same nodes
//!   and sources, same counters), and unfreezing selects for the frame's camera again;
//! - `Renderer::resize`: after resizing, a frame equals (byte for byte; PSNR ≥ 50 dB asserted) the frame of
//!   a renderer created at that size; an empty size is refused.

use atlastree::camera::Camera;
use atlastree::gpu::GpuContext;
use atlastree::ids::NodeId;
use atlastree::render::{FrameLoop, Mode, RenderError, RendererOptions};
use atlastree::select::{SelectOptions, Source, min_distance_scale};
use atlastree::store::TreeFile;

use crate::harness::GpuTest;
use crate::render::{bounds, city, psnr_covered};

pub fn tests() -> Vec<GpuTest> {
    vec![
        GpuTest {
            name: "view::frozen_selection_keeps_the_cut",
            run: frozen_selection_keeps_the_cut,
        },
        GpuTest {
            name: "view::resize_matches_a_fresh_renderer",
            run: resize_matches_a_fresh_renderer,
        },
    ]
}

const W: u32 = 320;
const H: u32 = 240;

fn e<E: std::fmt::Display>(x: E) -> String {
    x.to_string()
}

/// A close street-level camera (many fine nodes) and a distant overview camera (few coarse nodes).
fn cameras(file: &TreeFile) -> Result<(Camera, Camera), String> {
    let (lo, hi) = bounds(file)?;
    let up = file.to_params().up.vector();
    let centre = (lo + hi) * 0.5;
    let diag = (hi - lo).length();
    let horizontal = if up.z.abs() < 0.5 {
        glam::DVec3::Z
    } else {
        glam::DVec3::X
    };
    let cam = |eye, target| Camera {
        eye,
        target,
        up,
        fov_x_deg: 60.0,
        aspect: f64::from(W) / f64::from(H),
        near: 0.25,
        far: 1.0e5,
    };
    let street = cam(
        centre + up * (0.02 * diag) + horizontal * (0.1 * diag),
        centre,
    );
    let overview = cam(
        centre + up * (1.5 * diag) + horizontal * (0.5 * diag),
        centre,
    );
    Ok((street, overview))
}

fn scale(file: &TreeFile, width: u32, cam: &Camera) -> Result<f64, String> {
    min_distance_scale(
        &file.to_params(),
        &SelectOptions {
            screen_width: width,
            texel_ratio: 1.0,
            fov_x_deg: cam.fov_x_deg,
        },
    )
    .map_err(e)
}

fn renderer<'f>(
    ctx: &'f GpuContext,
    file: &'f TreeFile,
    w: u32,
    h: u32,
) -> Result<FrameLoop<'f>, String> {
    FrameLoop::new(ctx, file, RendererOptions::sized(w, h)).map_err(e)
}

fn selection(r: &FrameLoop<'_>) -> Vec<Vec<(NodeId, Source)>> {
    r.cuts().iter().map(|c| c.selection().collect()).collect()
}

fn frozen_selection_keeps_the_cut(ctx: &GpuContext) -> Result<(), String> {
    let file = TreeFile::open(&city()?).map_err(e)?;
    let (street, overview) = cameras(&file)?;
    let mut r = renderer(ctx, &file, W, H)?;
    let s_street = r
        .render(&street, scale(&file, W, &street)?, Mode::Tree)
        .map_err(e)?;
    let cut_street = selection(&r);
    let s_over = r
        .render(&overview, scale(&file, W, &overview)?, Mode::Tree)
        .map_err(e)?;
    let cut_over = selection(&r);
    if cut_street == cut_over {
        return Err(format!(
            "precondition: the street and overview views select the same cut ({} nodes)",
            s_street.plan.nodes_drawn
        ));
    }
    r.planner.freeze_selection(Some(street));
    let s_frozen = r
        .render(&overview, scale(&file, W, &street)?, Mode::Tree)
        .map_err(e)?;
    if selection(&r) != cut_street {
        return Err("the frozen frame did not keep the street view's cut".into());
    }
    if (
        s_frozen.plan.nodes_drawn,
        s_frozen.plan.nodes_visited,
        s_frozen.triangles,
    ) != (
        s_street.plan.nodes_drawn,
        s_street.plan.nodes_visited,
        s_street.triangles,
    ) {
        return Err(format!(
            "frozen counters {s_frozen:?} differ from the street frame's {s_street:?}"
        ));
    }
    r.planner.freeze_selection(None);
    let s_again = r
        .render(&overview, scale(&file, W, &overview)?, Mode::Tree)
        .map_err(e)?;
    if selection(&r) != cut_over || s_again.plan.nodes_drawn != s_over.plan.nodes_drawn {
        return Err("after unfreezing the overview did not select its own cut again".into());
    }
    println!(
        "    street cut {} nodes, overview cut {} nodes; frozen overview frame drew {}",
        s_street.plan.nodes_drawn, s_over.plan.nodes_drawn, s_frozen.plan.nodes_drawn
    );
    Ok(())
}

fn resize_matches_a_fresh_renderer(ctx: &GpuContext) -> Result<(), String> {
    let file = TreeFile::open(&city()?).map_err(e)?;
    let (street, _) = cameras(&file)?;
    let (w2, h2) = (W / 2 + 16, H / 2);
    let mut cam = street;
    cam.aspect = f64::from(w2) / f64::from(h2);
    let mut r = renderer(ctx, &file, W, H)?;
    r.render(&street, scale(&file, W, &street)?, Mode::Tree)
        .map_err(e)?;
    match r.renderer.resize(0, 10) {
        Err(RenderError::BadSize {
            width: 0,
            height: 10,
            ..
        }) => {}
        other => return Err(format!("resize(0, 10) gave {other:?}")),
    }
    // Past the device's largest texture: an error, not wgpu's uncaptured validation panic.
    let limit = ctx.device.limits().max_texture_dimension_2d;
    match r.renderer.resize(limit + 1, 1) {
        Err(RenderError::BadSize {
            width, limit: l, ..
        }) if width == limit + 1 && l == limit => {}
        other => return Err(format!("resize({}, 1) gave {other:?}", limit + 1)),
    }
    r.renderer.resize(w2, h2).map_err(e)?;
    r.render(&cam, scale(&file, w2, &cam)?, Mode::Tree)
        .map_err(e)?;
    let resized = r.read_frame().map_err(e)?;
    if resized.len() != (w2 * h2 * 4) as usize || r.renderer.color.width() != w2 {
        return Err(format!(
            "resized frame has {} bytes, expected {}",
            resized.len(),
            w2 * h2 * 4
        ));
    }
    let mut fresh = renderer(ctx, &file, w2, h2)?;
    fresh
        .render(&cam, scale(&file, w2, &cam)?, Mode::Tree)
        .map_err(e)?;
    let reference = fresh.read_frame().map_err(e)?;
    let (psnr, covered) = psnr_covered(&resized, &reference);
    println!("    resized vs fresh renderer: PSNR {psnr:.2} dB over {covered} covered pixels");
    if covered < (w2 * h2 / 10) as usize || psnr < 50.0 {
        return Err(format!(
            "PSNR {psnr:.2} dB over {covered} pixels (need ≥ 50 dB over ≥ 10 %)"
        ));
    }
    Ok(())
}
