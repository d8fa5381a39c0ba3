//! `citygen`: deterministic, seeded synthetic planar cities as glTF 2.0 + PNG/JPEG, shaped like the test
//! scenes of Buchholz & Döllner 2005 §7 (Berlin: 4,300 block buildings with one labelled 512² facade
//! texture each, repeated around the facade; Chemnitz: ~2,000 irregular textures, massively repeated ground
//! tiles, alpha-tested and blended parts).
//!
//! Output: `DIR/scene.gltf`, `DIR/scene.bin`, `DIR/textures/*`, `DIR/citygen.json`. Y up, metres, the
//! distribution plane is x–z. The same arguments give byte-identical files (textures are generated in
//! parallel, each from its own seed).

mod city;
mod encode;
mod font;
mod geom;
mod gltf_out;
mod rng;
mod texgen;

use anyhow::{Context, Result, bail};
use clap::{Parser, ValueEnum};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Which city to generate.
#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
enum Kind {
    /// 4,300·S block buildings on a street grid, each with its own facade texture showing its id in large
    /// digits, repeated every 10 m × 12 m around the walls; 3 shared roof textures; an asphalt ground
    /// repeated every 4 m; every 40th building has a rotated twin instancing its mesh.
    Berlin,
    /// An irregular district: a pool of 2,000·S textures from 16² to 2048² (mostly small), star- and
    /// L-shaped footprints with per-storey walls (3,000·S buildings), ground and plazas as single large
    /// triangles with u, v up to ±300, MIRRORED_REPEAT and CLAMP_TO_EDGE samplers, fences (MASK 0.5),
    /// crossed-quad trees (BLEND), palette signs, JPEG photos, untextured roofs.
    Chemnitz,
    /// A small blend: 24·S Berlin buildings (256² facades) next to a Chemnitz district with at least ⌈N/3⌉
    /// buildings (as many as its facade and roof sets need) and a 24·S-texture pool capped at 256² (the committed fixture `data/city`).
    Mixed,
}

/// Deterministic synthetic planar cities (glTF 2.0 + PNG/JPEG) for texture-atlas-tree tests.
///
/// Example: `citygen berlin --scale 0.005 --out /tmp/berlin20` writes about 20 buildings. The committed
/// fixture is `citygen mixed --seed 1 --out data/city` (see data/README.md).
#[derive(Parser, Debug)]
#[command(
    name = "citygen",
    version,
    after_help = "Examples:\n  citygen berlin --scale 0.005 --out /tmp/berlin20\n  citygen berlin --scale 1 --png fast --out /tmp/berlin1      (4,300 buildings, 512² facades)\n  citygen chemnitz --scale 1 --out /tmp/chemnitz1\n  citygen mixed --seed 1 --buildings 24 --facade-size 256 --out data/city\n\nWrites DIR/scene.gltf, DIR/scene.bin, DIR/textures/*.png|jpg and DIR/citygen.json (parameters and counts)."
)]
struct Cli {
    /// Scene type (see the list below for what each contains).
    #[arg(value_enum)]
    kind: Kind,
    /// Output directory; must be empty or absent unless --overwrite is given.
    #[arg(long)]
    out: PathBuf,
    /// Random seed; the same seed and arguments give byte-identical output.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Multiplies the default counts (buildings, pool textures): --scale 0.005 gives ~20 Berlin buildings.
    #[arg(long, default_value_t = 1.0)]
    scale: f64,
    /// Number of buildings, overriding round(default·scale) (berlin: 4,300; chemnitz: 3,000; mixed: 24).
    #[arg(long)]
    buildings: Option<u32>,
    /// Facade texture edge in texels (berlin: 512, mixed: 256); for chemnitz, the largest pool texture
    /// edge (2048).
    #[arg(long)]
    facade_size: Option<u32>,
    /// Texture pool size of the irregular district (chemnitz: 2,000·scale; mixed: 24·scale; at least 11).
    #[arg(long)]
    textures: Option<u32>,
    /// PNG compression effort (high for fixtures; fast for huge scenes).
    #[arg(long, value_enum, default_value_t = encode::PngEffort::High)]
    png: encode::PngEffort,
    /// Replace an existing output (removes scene.gltf, scene.bin, citygen.json and textures/*.png|jpg).
    #[arg(long)]
    overwrite: bool,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
}

/// Everything `citygen.json` records: the arguments, the resolved parameters and the counts.
#[derive(serde::Serialize)]
struct Report<'a> {
    generator: String,
    kind: Kind,
    seed: u64,
    scale: f64,
    png: encode::PngEffort,
    command: String,
    berlin: Option<city::BerlinParams>,
    chemnitz: Option<city::ChemnitzParams>,
    counts: &'a city::Counts,
    scene: gltf_out::SceneStats,
    texels_with_repetition: u64,
    textures: TextureTotals,
    files: Files,
}

#[derive(serde::Serialize, Default)]
struct TextureTotals {
    images: u64,
    texels: u64,
    bytes: u64,
    min_edge: u32,
    max_edge: u32,
    png_rgb: u64,
    png_rgba: u64,
    png_grey: u64,
    png_palette: u64,
    jpeg: u64,
}

#[derive(serde::Serialize, Default)]
struct Files {
    gltf_bytes: u64,
    bin_bytes: u64,
}

fn scaled(base: f64, scale: f64) -> u32 {
    (base * scale).round().clamp(1.0, f64::from(u32::MAX)) as u32
}

/// Most buildings and pool textures one run makes (a city of 500,000 buildings fits; `--scale 1e30` or
/// `--textures 4000000000` aborted on a 128 GB allocation, leaving a half-made folder).
const MAX_BUILDINGS: u32 = 2_000_000;
const MAX_TEXTURES: u32 = 1_000_000;

/// The resolved district parameters for `cli`, refused past [`MAX_BUILDINGS`] and [`MAX_TEXTURES`]
/// before anything is written.
fn params(cli: &Cli) -> Result<(Option<city::BerlinParams>, Option<city::ChemnitzParams>)> {
    let resolved = district_params(cli)?;
    let (berlin, chemnitz) = &resolved;
    let buildings = berlin.as_ref().map_or(0, |b| b.buildings) as u64
        + chemnitz.as_ref().map_or(0, |c| c.buildings) as u64;
    if buildings > u64::from(MAX_BUILDINGS) {
        bail!(
            "--scale {} gives {buildings} buildings; at most {MAX_BUILDINGS} (--buildings sets the count)",
            cli.scale
        );
    }
    if let Some(c) = chemnitz
        && c.textures > MAX_TEXTURES
    {
        bail!(
            "{} pool textures (--textures, or --scale {}); at most {MAX_TEXTURES}",
            c.textures,
            cli.scale
        );
    }
    Ok(resolved)
}

fn district_params(
    cli: &Cli,
) -> Result<(Option<city::BerlinParams>, Option<city::ChemnitzParams>)> {
    if !(cli.scale.is_finite() && cli.scale > 0.0) {
        bail!(
            "--scale must be a positive finite number, got {}",
            cli.scale
        );
    }
    if let Some(s) = cli.facade_size
        && !(16..=8192).contains(&s)
    {
        bail!("--facade-size must be in 16..=8192 texels, got {s}");
    }
    if cli.buildings == Some(0) {
        bail!("--buildings must be at least 1");
    }
    Ok(match cli.kind {
        Kind::Berlin => (
            Some(city::BerlinParams {
                buildings: cli.buildings.unwrap_or_else(|| scaled(4300.0, cli.scale)),
                facade_size: cli.facade_size.unwrap_or(512),
                roof_size: 256,
                ground_size: 256,
                origin: [0.0, 0.0],
            }),
            None,
        ),
        Kind::Chemnitz => (
            None,
            Some(city::ChemnitzParams {
                buildings: cli.buildings.unwrap_or_else(|| scaled(3000.0, cli.scale)),
                textures: cli.textures.unwrap_or_else(|| scaled(2000.0, cli.scale)),
                max_size: cli.facade_size.unwrap_or(2048),
                origin: [0.0, 0.0],
            }),
        ),
        Kind::Mixed => {
            let n = cli.buildings.unwrap_or_else(|| scaled(24.0, cli.scale));
            (
                Some(city::BerlinParams {
                    buildings: n,
                    facade_size: cli.facade_size.unwrap_or(256),
                    roof_size: 128,
                    ground_size: 256,
                    origin: [0.0, 0.0],
                }),
                // The origin is placed beyond the Berlin part once its extent is known.
                Some(city::ChemnitzParams {
                    buildings: n.div_ceil(3),
                    textures: cli.textures.unwrap_or_else(|| scaled(24.0, cli.scale)),
                    max_size: 256,
                    origin: [0.0, 0.0],
                }),
            )
        }
    })
}

/// Creates `out` and `out/textures`, refusing to mix with an existing non-empty directory unless
/// `overwrite`, in which case only files citygen writes are removed.
fn prepare_dir(out: &Path, overwrite: bool) -> Result<()> {
    let non_empty = out
        .read_dir()
        .map(|mut d| d.next().is_some())
        .unwrap_or(false);
    if non_empty {
        if !overwrite {
            bail!(
                "{} exists and is not empty; pass --overwrite to replace a previous citygen output",
                out.display()
            );
        }
        for f in ["scene.gltf", "scene.bin", "citygen.json"] {
            let p = out.join(f);
            if p.exists() {
                std::fs::remove_file(&p).with_context(|| format!("removing {}", p.display()))?;
            }
        }
        let tex = out.join("textures");
        if let Ok(entries) = tex.read_dir() {
            for e in entries {
                let p = e
                    .with_context(|| format!("listing {}", tex.display()))?
                    .path();
                if matches!(p.extension().and_then(|e| e.to_str()), Some("png" | "jpg")) {
                    std::fs::remove_file(&p)
                        .with_context(|| format!("removing {}", p.display()))?;
                }
            }
        }
    }
    let tex = out.join("textures");
    std::fs::create_dir_all(&tex).with_context(|| format!("creating {}", tex.display()))
}

fn progress(n: u64, quiet: bool) -> indicatif::ProgressBar {
    if quiet {
        return indicatif::ProgressBar::hidden();
    }
    let pb = indicatif::ProgressBar::new(n);
    let style = indicatif::ProgressStyle::with_template(
        "{msg} [{elapsed_precise}] {wide_bar} {pos}/{len} textures ({eta} left)",
    )
    .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar());
    pb.set_style(style);
    pb.set_message("citygen");
    pb
}

/// Generates, encodes and writes every texture in parallel; returns the file sizes in input order.
fn write_textures(
    specs: &[texgen::TexSpec],
    dir: &Path,
    effort: encode::PngEffort,
    quiet: bool,
) -> Result<Vec<u64>> {
    let pb = progress(specs.len() as u64, quiet);
    let sizes = specs
        .par_iter()
        .map(|spec| -> Result<u64> {
            let px = texgen::generate(spec);
            let bytes = encode::encode(&px, spec.encoding, effort)
                .with_context(|| format!("encoding {}", spec.file))?;
            let path = dir.join(&spec.file);
            std::fs::write(&path, &bytes).with_context(|| format!("writing {}", path.display()))?;
            pb.inc(1);
            Ok(bytes.len() as u64)
        })
        .collect::<Result<Vec<u64>>>()?;
    pb.finish_and_clear();
    Ok(sizes)
}

fn texture_totals(specs: &[texgen::TexSpec], sizes: &[u64]) -> TextureTotals {
    use texgen::Encoding as E;
    let mut t = TextureTotals {
        min_edge: u32::MAX,
        ..Default::default()
    };
    for (s, b) in specs.iter().zip(sizes) {
        t.images += 1;
        t.texels += u64::from(s.width) * u64::from(s.height);
        t.bytes += b;
        t.min_edge = t.min_edge.min(s.width.min(s.height));
        t.max_edge = t.max_edge.max(s.width.max(s.height));
        *match s.encoding {
            E::PngRgb => &mut t.png_rgb,
            E::PngRgba => &mut t.png_rgba,
            E::PngGrey => &mut t.png_grey,
            E::PngPalette => &mut t.png_palette,
            E::Jpeg => &mut t.jpeg,
        } += 1;
    }
    if t.images == 0 {
        t.min_edge = 0;
    }
    t
}

/// The command line that reproduces this output (recorded in citygen.json).
fn command_line(cli: &Cli) -> String {
    let mut c = format!(
        "citygen {} --seed {} --scale {} --png {}",
        format!("{:?}", cli.kind).to_lowercase(),
        cli.seed,
        cli.scale,
        format!("{:?}", cli.png).to_lowercase()
    );
    for (flag, v) in [
        ("--buildings", cli.buildings),
        ("--facade-size", cli.facade_size),
        ("--textures", cli.textures),
    ] {
        if let Some(v) = v {
            c.push_str(&format!(" {flag} {v}"));
        }
    }
    c
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    let t0 = Instant::now();
    let (berlin, mut chemnitz) = params(&cli)?;
    prepare_dir(&cli.out, cli.overwrite)?;

    let mut c = city::City::new(cli.seed);
    if let Some(p) = &berlin {
        let extent = city::berlin(&mut c, p);
        if let Some(ch) = chemnitz.as_mut() {
            ch.origin = [0.0, extent[1] + 60.0];
        }
    }
    if let Some(p) = &chemnitz {
        city::chemnitz(&mut c, p);
    }
    let sizes = write_textures(&c.textures, &cli.out.join("textures"), cli.png, cli.quiet)?;
    let textures = texture_totals(&c.textures, &sizes);
    let scene = c.gltf.stats();
    let (json, bin) = c
        .gltf
        .finish("scene.bin", concat!("citygen ", env!("CARGO_PKG_VERSION")))?;
    std::fs::write(cli.out.join("scene.bin"), &bin).context("writing scene.bin")?;
    std::fs::write(cli.out.join("scene.gltf"), &json).context("writing scene.gltf")?;

    let report = Report {
        generator: concat!("citygen ", env!("CARGO_PKG_VERSION")).to_string(),
        kind: cli.kind,
        seed: cli.seed,
        scale: cli.scale,
        png: cli.png,
        command: command_line(&cli),
        berlin,
        chemnitz,
        counts: &c.counts,
        scene,
        texels_with_repetition: scene.texels_with_repetition.round() as u64,
        textures,
        files: Files {
            gltf_bytes: json.len() as u64,
            bin_bytes: bin.len() as u64,
        },
    };
    let mut text = serde_json::to_vec_pretty(&report).context("serialising citygen.json")?;
    text.push(b'\n');
    std::fs::write(cli.out.join("citygen.json"), &text).context("writing citygen.json")?;

    let total = report.textures.bytes
        + report.files.gltf_bytes
        + report.files.bin_bytes
        + text.len() as u64;
    eprintln!(
        "citygen: {} buildings (+{} instances), {} irregular, {} triangles, {} images ({:.1} Mtexel), {:.1} MB in {}, {:.2} s",
        c.counts.block_buildings,
        c.counts.block_instances,
        c.counts.irregular_buildings,
        scene.triangles,
        report.textures.images,
        report.textures.texels as f64 / 1e6,
        total as f64 / 1e6,
        cli.out.display(),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}
