//! The supersampled reference (`--reference supersampled[:S]`, `Renderer::execute_supersampled`):
//!
//! - where nothing is minified (a checker ground magnified ~17× under a camera looking straight down, the
//!   quad filling the view), the supersampled reference (S = 4) and the plain original frame agree:
//!   PSNR ≥ 40 dB over the whole frame (bilinear magnification is linear between texel centres, and a
//!   box average of a linear function is its centre value);
//! - the GPU downsample is the CPU twin `report::supersample::box_downsample_linear` of the read-back
//!   supersampled frame to ±1/255 per channel, on a view where the checker's texels are 0.6 output
//!   pixels wide; and it is linear light, not an average of sRGB codes: there the two differ by ≥ 25
//!   codes somewhere (black and white average to 188 in linear light, to 128 in sRGB codes; an sRGB-code
//!   average on the GPU would match this one to ±1).

use atlastree::camera::Camera;
use atlastree::gpu::GpuContext;
use atlastree::preprocess::{BuildOptions, DMin, NoProgress, build};
use atlastree::render::{FrameLoop, Mode, RenderError, RendererOptions};
use atlastree::report::metrics::psnr;
use atlastree::report::supersample::box_downsample_linear;
use atlastree::scene::synthetic::SceneBuilder;
use atlastree::scene::{AlphaMode, UpAxis, Wrap};
use atlastree::store::TreeFile;
use glam::{DVec2, DVec3};

use crate::harness::GpuTest;
use crate::render::{H, W, e, scale_for};

pub fn tests() -> Vec<GpuTest> {
    vec![
        GpuTest {
            name: "reference::supersampled_agrees_with_the_original_where_nothing_is_minified",
            run: supersampled_agrees_where_nothing_is_minified,
        },
        GpuTest {
            name: "reference::downsample_is_the_cpu_twin_in_linear_light",
            run: downsample_is_the_cpu_twin_in_linear_light,
        },
    ]
}

const FACTOR: u32 = 4;
/// Side of the ground quad, metres, and of its black-and-white checker texture, texels (8-texel cells).
const SIDE: f64 = 40.0;
const TEXELS: u32 = 64;

/// A 40 m ground quad with a 64² black-and-white checker of 8-texel cells (clamped), built into the test
/// scratch dir.
fn checker_file() -> Result<std::path::PathBuf, String> {
    let mut b = SceneBuilder::new(UpAxis::Y);
    let img = b.image("checker", TEXELS, TEXELS, |x, y| {
        let v = if (x / 8 + y / 8).is_multiple_of(2) {
            255
        } else {
            0
        };
        [v, v, v, 255]
    });
    let m = b.material(img, [Wrap::ClampToEdge; 2], AlphaMode::Opaque);
    let c =
        [(0.0, 0.0), (SIDE, 0.0), (SIDE, SIDE), (0.0, SIDE)].map(|(x, z)| DVec3::new(x, 0.0, z));
    b.quad(c, DVec2::ZERO, DVec2::ONE, m);
    let scene = b.build();
    let out = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("reference-checker.atlastree");
    let opts = BuildOptions {
        d_min: DMin::Ratio(10.0),
        atlas_size: 256,
        ..BuildOptions::default()
    };
    build(&scene, &opts, &out, &NoProgress).map_err(e)?;
    Ok(out)
}

/// Looking straight down on the quad's centre from `height` metres.
fn down(height: f64) -> Camera {
    let centre = DVec3::new(SIDE / 2.0, 0.0, SIDE / 2.0);
    Camera {
        eye: centre + DVec3::new(0.0, height, 0.0),
        target: centre,
        up: DVec3::Z,
        fov_x_deg: 60.0,
        aspect: f64::from(W) / f64::from(H),
        near: 0.1,
        far: 10.0 * height,
    }
}

/// The plain original frame and the supersampled reference of `cam`.
fn frames(
    fl: &mut FrameLoop<'_>,
    file: &TreeFile,
    cam: &Camera,
) -> Result<(Vec<u8>, Vec<u8>), String> {
    let s = scale_for(file, cam)?;
    let plan = fl
        .planner
        .plan_still(cam, s, &mut fl.renderer.residency())
        .map_err(e)?;
    fl.renderer.execute(plan, Mode::Original).map_err(e)?;
    let plain = fl.renderer.read_frame().map_err(e)?;
    let truth = fl.renderer.execute_supersampled(plan, FACTOR).map_err(e)?;
    Ok((plain, truth))
}

fn open<'f>(ctx: &'f GpuContext, file: &'f TreeFile) -> Result<FrameLoop<'f>, String> {
    FrameLoop::new(
        ctx,
        file,
        RendererOptions {
            anisotropy: 1,
            ..RendererOptions::sized(W, H)
        },
    )
    .map_err(e)
}

fn supersampled_agrees_where_nothing_is_minified(ctx: &GpuContext) -> Result<(), String> {
    let path = checker_file()?;
    let file = TreeFile::open(&path).map_err(e)?;
    let mut fl = open(ctx, &file)?;
    // 10 m up: the view is 11.5 m wide, 320 px, so one 0.625 m texel covers ~17 px; the quad fills it.
    let (plain, truth) = frames(&mut fl, &file, &down(10.0))?;
    // A factor past the device's texture size is an error that names S, not the frame size.
    let limit = ctx.device.limits().max_texture_dimension_2d;
    let too_big = limit / W + 1;
    let cam = down(10.0);
    let plan = fl
        .planner
        .plan_still(&cam, scale_for(&file, &cam)?, &mut fl.renderer.residency())
        .map_err(e)?;
    // Asked before a run (render and sweep refuse it before removing or building anything).
    let check = atlastree::render::reference::check_supersample;
    if check(ctx, W, H, too_big).is_ok() || check(ctx, W, H, too_big - 1).is_err() {
        return Err(format!("check_supersample's limit is not {too_big}"));
    }
    match fl.renderer.execute_supersampled(plan, too_big) {
        Err(RenderError::BadSupersample {
            factor, limit: l, ..
        }) if factor == too_big && l == limit => {}
        other => {
            return Err(format!(
                "supersampled:{too_big} gave {:?}",
                other.map(|b| b.len())
            ));
        }
    }
    let db = psnr(&plain, &truth, W, H).map_err(e)?;
    // Not a flat frame: the checker's black and white are both in view.
    let (dark, light) = (
        plain.chunks(4).filter(|p| p[0] < 40).count(),
        plain.chunks(4).filter(|p| p[0] > 215).count(),
    );
    println!(
        "  magnified checker: supersampled vs plain original {db:.2} dB ({dark} dark, {light} light px)"
    );
    if dark == 0 || light == 0 {
        return Err(format!(
            "the view shows no checker ({dark} dark, {light} light pixels)"
        ));
    }
    if db < 40.0 {
        return Err(format!(
            "supersampled and plain original differ: {db:.2} dB < 40 dB"
        ));
    }
    Ok(())
}

fn downsample_is_the_cpu_twin_in_linear_light(ctx: &GpuContext) -> Result<(), String> {
    let path = checker_file()?;
    let file = TreeFile::open(&path).map_err(e)?;
    let mut fl = open(ctx, &file)?;
    // 277 m up: the view is 320 m wide, so the 64 texels span ~40 px (1.6 texels per pixel) and
    // ~160 px at S = 4 (magnified there: the supersampled frame shows the checker itself).
    let (_, truth) = frames(&mut fl, &file, &down(277.0))?;
    let (sw, sh, big) = fl
        .renderer
        .read_supersampled()
        .map_err(e)?
        .ok_or("no supersampled frame")?;
    if (sw, sh) != (W * FACTOR, H * FACTOR) {
        return Err(format!("supersampled frame {sw}×{sh}"));
    }
    let twin = box_downsample_linear(&big, sw, sh, FACTOR).map_err(e)?;
    let worst = truth
        .iter()
        .zip(&twin)
        .map(|(a, b)| a.abs_diff(*b))
        .max()
        .unwrap_or(0);
    // The same blocks averaged as sRGB codes (wrong): far from the GPU's somewhere on the checker.
    let mut far = 0u8;
    let s = FACTOR as usize;
    for y in 0..H as usize {
        for x in 0..W as usize {
            for c in 0..3 {
                let mut sum = 0u32;
                for dy in 0..s {
                    for dx in 0..s {
                        sum += u32::from(big[((y * s + dy) * sw as usize + x * s + dx) * 4 + c]);
                    }
                }
                let naive = ((sum as f64) / (s * s) as f64).round() as u8;
                far = far.max(naive.abs_diff(truth[(y * W as usize + x) * 4 + c]));
            }
        }
    }
    println!(
        "  downsample: GPU vs CPU twin max {worst}/255; vs an sRGB-code average up to {far}/255"
    );
    if worst > 1 {
        return Err(format!(
            "GPU downsample differs from its CPU twin by {worst}/255"
        ));
    }
    if far < 25 {
        return Err(format!(
            "the view cannot tell linear from sRGB averaging (at most {far}/255 apart)"
        ));
    }
    Ok(())
}
