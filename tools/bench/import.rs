//! `cargo bench --bench import`: `scene::import` throughput on a generated 6.2M-triangle, 900-texture glTF
//! scene (`tests/fixtures/tiled_gltf.rs`: 30 × 30 tiles of 34² quads, instanced three times; ~150 MB
//! written to a temp dir first). One iteration = one whole import; criterion prints triangles/s. That
//! every triangle and image arrives is `tests/cpu/import/tiled.rs` (the same scene, smaller).

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "benchmark code: a failed unwrap fails the run loudly"
)]

#[path = "../../tests/fixtures/tiled_gltf.rs"]
mod tiled_gltf;

use atlastree::scene::{ImportOptions, import};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;
use std::time::Duration;

const TILES: usize = 30;
const QUADS: usize = 34;

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let path = tiled_gltf::write(dir.path(), TILES, QUADS);
    let tris = tiled_gltf::triangles(TILES, QUADS);
    let mut g = c.benchmark_group("import");
    g.sample_size(10)
        .measurement_time(Duration::from_secs(30))
        .throughput(Throughput::Elements(tris as u64));
    g.bench_function("6.2m-triangles-900-textures", |b| {
        b.iter(|| {
            let s = import(&path, &ImportOptions::default()).unwrap();
            assert_eq!(s.triangles.len(), tris);
            black_box(s.images.len())
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
