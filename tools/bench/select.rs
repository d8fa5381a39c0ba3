//! `cargo bench --bench select`: CPU time of the per-frame cut (paper §4) on a synthetic Berlin-sized
//! tree (10 km × 10 km, depth 7, ~3,500 nodes) for 200 cameras along generated paths. One criterion
//! iteration = one frame (frustum + traversal), cycling through the cameras, so the reported time is
//! per frame. Target: < 50 µs on one core.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "benchmark code: a failed unwrap fails the run loudly"
)]

#[path = "../../tests/fixtures/select_trees.rs"]
mod select_trees;

use atlastree::camera::CameraPath;
use atlastree::scene::UpAxis;
use atlastree::select::{Cut, CutStats, select};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let nodes = select_trees::berlin(3);
    let (lo, hi) = (nodes[0].bounds_min.into(), nodes[0].bounds_max.into());
    let mut group = c.benchmark_group("select");
    let dive = CameraPath::overview_dive(lo, hi, UpAxis::Y);
    let street = CameraPath::street(lo, hi, UpAxis::Y);
    // scale 4: e.g. a 3840-pixel screen at texel ratio 2 on a tree built for 1920 at 1:1 (finer cuts).
    for (name, path, scale) in [
        ("overview-dive", &dive, 1.0),
        ("street", &street, 1.0),
        ("overview-dive-scale4", &dive, 4.0),
    ] {
        let Ok(path) = path else { continue };
        let cameras: Vec<_> = path.frames(200.0 / path.duration(), 200).collect();
        let mut cut = Cut::new();
        let (mut items, mut visited, mut originals) = (0u64, 0u64, 0u64);
        for cam in &cameras {
            select(&nodes, cam, &cam.frustum(), scale, &mut cut);
            let s = CutStats::of(&cut);
            items += u64::from(s.nodes());
            visited += u64::from(s.visited);
            originals += u64::from(s.original_nodes);
        }
        let n = cameras.len() as f64;
        eprintln!(
            "select/{name}: {} nodes; per frame over {} cameras: {:.1} items ({:.1} original), {:.1} visited",
            nodes.len(),
            cameras.len(),
            items as f64 / n,
            originals as f64 / n,
            visited as f64 / n,
        );
        let mut i = 0usize;
        group.bench_function(name, |b| {
            b.iter(|| {
                let cam = &cameras[i % cameras.len()];
                i += 1;
                select(black_box(&nodes), cam, &cam.frustum(), scale, &mut cut);
                black_box(cut.items.len())
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
