use super::{UpArg, load_scene};
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Args, Debug)]
pub(crate) struct SceneInfoArgs {
    /// The glTF scene (.gltf or .glb).
    pub scene: PathBuf,
    /// Up axis; `auto` takes the axis of least extent where it is under half the next least, else y
    /// (glTF's convention).
    #[arg(long, value_enum, default_value_t = UpArg::Auto)]
    pub up: UpArg,
    /// Keep only the triangles of these materials (comma-separated globs, as `build --materials`).
    #[arg(long, value_delimiter = ',', value_name = "GLOB")]
    pub materials: Vec<String>,
    /// Also decode every used image once (all cores) and report the time: the baseline of the build's
    /// throughput target.
    #[arg(long)]
    pub decode: bool,
    /// Print JSON instead of text (for scripts).
    #[arg(long)]
    pub json: bool,
}

pub(super) fn run(a: SceneInfoArgs) -> anyhow::Result<ExitCode> {
    let t = std::time::Instant::now();
    let mut scene = load_scene(&a.scene, a.up)?;
    if !a.materials.is_empty() {
        super::retain_materials(&mut scene, &a.materials)?;
    }
    let import_s = t.elapsed().as_secs_f64();
    let info = atlastree::scene::info::analyze(&scene);
    let decode = a.decode.then(|| atlastree::scene::info::decode_all(&scene));
    if a.json {
        let mut v = serde_json::to_value(&info)?;
        if let Some(o) = v.as_object_mut() {
            o.insert("import_seconds".into(), import_s.into());
            if let Some(d) = &decode {
                o.insert("decode".into(), serde_json::to_value(d)?);
            }
            o.insert(
                "peak_rss_bytes".into(),
                atlastree::util::peak_rss_bytes().into(),
            );
        }
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!("{info}");
        if let Some(d) = &decode {
            println!("{d}");
        }
        println!(
            "imported in {import_s:.2} s, peak memory {}",
            atlastree::util::peak_rss_bytes().map_or("?".into(), atlastree::util::human_bytes)
        );
    }
    Ok(ExitCode::SUCCESS)
}
