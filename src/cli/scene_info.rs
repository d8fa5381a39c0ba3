use super::{UpArg, load_scene};
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Args, Debug)]
pub struct SceneInfoArgs {
    /// The glTF scene (.gltf or .glb).
    pub scene: PathBuf,
    /// Up axis; `auto` takes the axis of least extent.
    #[arg(long, value_enum, default_value_t = UpArg::Auto)]
    pub up: UpArg,
    /// Print JSON instead of text (for scripts).
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: SceneInfoArgs) -> anyhow::Result<ExitCode> {
    let t = std::time::Instant::now();
    let scene = load_scene(&a.scene, a.up)?;
    let import_s = t.elapsed().as_secs_f64();
    let info = atlastree::scene::info::analyze(&scene);
    if a.json {
        let mut v = serde_json::to_value(&info)?;
        if let Some(o) = v.as_object_mut() {
            o.insert("import_seconds".into(), import_s.into());
            o.insert(
                "peak_rss_bytes".into(),
                atlastree::util::peak_rss_bytes().into(),
            );
        }
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!("{info}");
        println!(
            "imported in {import_s:.2} s, peak memory {}",
            atlastree::util::peak_rss_bytes().map_or("?".into(), atlastree::util::human_bytes)
        );
    }
    Ok(ExitCode::SUCCESS)
}
