//! `cargo bench --bench pipeline`: the hot paths of the build and of a frame, each with its throughput
//! (criterion prints elements/s next to the time):
//!
//! - `sizing`: per-triangle sizing of data/city (paper §5.2.1, `preprocess::prepare::prepare`), triangles/s;
//! - `packing`: MaxRects packing of 200 rects (8–60 texels a side) into one 1024² atlas (§5.2.3, `preprocess::pack::pack`), rects/s;
//! - `raster`: one 256² packed area of a leaf atlas drawn from a 512² source mip chain
//!   (`image_ops::draw_rect`, minification-correct footprint sampling), texels/s;
//! - `downsample`: one 1024² → 512² mip level, box and Kaiser (`image_ops::downsample`), source texels/s;
//! - `select`: the per-frame cut of a synthetic Berlin-sized tree (§4), nodes of the tree per second;
//! - `priority`: the paging usage traversal (`paging::classify`) and a full `Pager::plan` (§6) on
//!   the same tree with one atlas block per node and one original block per leaf, nodes/s.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "benchmark code: a failed unwrap fails the run loudly"
)]

#[path = "../../tests/fixtures/select_trees.rs"]
mod select_trees;

use atlastree::camera::{Camera, CameraPath};
use atlastree::ids::NONE;
use atlastree::paging::{BlockTable, Pager, PagerOptions, ViewInput};
use atlastree::paging::{UsageScratch, classify};
use atlastree::preprocess::image_ops::{
    LinearImage, MipChain, MipFilter, MipOptions, RectJob, downsample, draw_rect,
};
use atlastree::preprocess::pack::{PackOptions, pack};
use atlastree::preprocess::prepare::{PrepareOptions, prepare};
use atlastree::preprocess::{BuildOptions, resolve_params};
use atlastree::scene::{UpAxis, Wrap};
use atlastree::select::{Cut, select};
use atlastree::store::format::{BLOCK_ATLAS, BLOCK_ORIGINALS, BlockRecord, NodeRecord};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;
use std::path::Path;

/// A deterministic noise texture (xorshift), premultiplied opaque.
fn noise(w: u32, h: u32) -> LinearImage {
    let mut s = 0x2545_f491_u32;
    let mut img = LinearImage::new_filled(w, h, [0.0; 4]);
    for t in &mut img.data {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        let v = (s % 1000) as f32 / 1000.0;
        *t = [v, 1.0 - v, 0.5 * v, 1.0];
    }
    img
}

fn sizing(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/city/scene.gltf");
    // A bench that cannot run fails loudly: a silently missing row would hide a regression.
    let scene = atlastree::scene::import(&path, &Default::default()).expect("data/city imports");
    let (params, _) =
        resolve_params(&scene, &BuildOptions::default()).expect("default options are valid");
    let tris: Vec<u32> = (0..scene.triangles.len() as u32).collect();
    let opts = PrepareOptions {
        f_proj: params.f_proj(),
        up: params.up,
        cap_to_source: true,
        split_limit: f64::from(params.atlas_size / 4),
        max_pieces: 4096,
        wrap: true,
        palette_cells: 0,
    };
    let mut g = c.benchmark_group("sizing");
    g.throughput(Throughput::Elements(tris.len() as u64));
    g.bench_function("data-city", |b| {
        b.iter(|| black_box(prepare(&scene, &tris, &opts).infos.len()))
    });
    g.finish();
}

fn packing(c: &mut Criterion) {
    let mut s = 12345u32;
    let sizes: Vec<[u32; 2]> = (0..200)
        .map(|_| {
            s = s.wrapping_mul(1_103_515_245).wrapping_add(12345);
            let w = 8 + 4 * ((s >> 8) % 14);
            s = s.wrapping_mul(1_103_515_245).wrapping_add(12345);
            let h = 8 + 4 * ((s >> 8) % 14);
            [w, h]
        })
        .collect();
    let opts = PackOptions {
        atlas_size: 1024,
        ..PackOptions::default()
    };
    // pack wants multiples of 4 texels; a failed packing would time only the early exit.
    if let Err(e) = pack(&sizes, &opts) {
        panic!("packing: the benchmark rects do not pack ({e})");
    }
    let mut g = c.benchmark_group("packing");
    g.throughput(Throughput::Elements(sizes.len() as u64));
    g.bench_function("200-rects-1024", |b| {
        b.iter(|| black_box(pack(&sizes, &opts).is_ok()))
    });
    g.finish();
}

fn raster(c: &mut Criterion) {
    let src = MipChain::build(noise(512, 512));
    let mut dst = LinearImage::new_filled(1024, 1024, [0.0; 4]);
    // 256² area showing 1.5 repetitions of the source: minified 3× on each axis, wrapped.
    let job = RectJob {
        outer: [100, 100, 272, 272],
        inner: [108, 108, 256, 256],
        uv_min: [0.0, 0.0],
        uv_max: [1.5, 1.5],
        wrap: [Wrap::Repeat; 2],
        factor: [1.0; 4],
    };
    let mut g = c.benchmark_group("raster");
    g.throughput(Throughput::Elements(272 * 272));
    g.bench_function("draw_rect-256", |b| {
        b.iter(|| draw_rect(black_box(&mut dst), &job, &src).is_ok())
    });
    g.finish();
}

fn downsampling(c: &mut Criterion) {
    let img = noise(1024, 1024);
    let mut g = c.benchmark_group("downsample");
    g.throughput(Throughput::Elements(1024 * 1024));
    for f in MipFilter::ALL {
        let opts = MipOptions {
            filter: f,
            ..MipOptions::default()
        };
        g.bench_function(format!("1024-{}", f.name()), |b| {
            b.iter(|| black_box(downsample(&img, &opts).data.len()))
        });
    }
    g.finish();
}

/// One atlas block per node and one original block per leaf (as tests/cpu/paging/props.rs).
fn blocks_for(nodes: &[NodeRecord]) -> Vec<BlockRecord> {
    let rec = |kind, item, length| BlockRecord {
        offset: 0,
        length,
        checksum: 0,
        tree: 0,
        kind,
        item,
        part: 0,
        sse: 0,
    };
    let mut v: Vec<BlockRecord> = (0..nodes.len() as u32)
        .map(|n| rec(BLOCK_ATLAS, n, 1 << 20))
        .collect();
    v.extend(
        nodes
            .iter()
            .filter(|n| n.leaf != NONE)
            .map(|n| rec(BLOCK_ORIGINALS, n.leaf, 1 << 19)),
    );
    v
}

fn cameras(nodes: &[NodeRecord]) -> Vec<Camera> {
    let (lo, hi) = (nodes[0].bounds_min.into(), nodes[0].bounds_max.into());
    CameraPath::overview_dive(lo, hi, UpAxis::Y)
        .map(|p| p.frames(200.0 / p.duration(), 200).collect())
        .unwrap_or_default()
}

fn selection_and_priority(c: &mut Criterion) {
    let nodes = select_trees::berlin(3);
    let cams = cameras(&nodes);
    assert!(
        !cams.is_empty(),
        "select: no cameras for the Berlin-like tree"
    );
    let n = nodes.len() as u64;
    let mut g = c.benchmark_group("select");
    g.throughput(Throughput::Elements(n));
    let mut cut = Cut::new();
    let mut i = 0usize;
    g.bench_function("berlin-dive", |b| {
        b.iter(|| {
            let cam = &cams[i % cams.len()];
            i += 1;
            select(black_box(&nodes), cam, &cam.frustum(), 1.0, &mut cut);
            black_box(cut.items.len())
        })
    });
    g.finish();

    let blocks = blocks_for(&nodes);
    let table = BlockTable::new(&[&nodes], &blocks).expect("priority: the block table is valid");
    let mut g = c.benchmark_group("priority");
    g.throughput(Throughput::Elements(n));
    let mut scratch = UsageScratch::default();
    let mut out = Vec::new();
    let mut i = 0usize;
    g.bench_function("classify-berlin-dive", |b| {
        b.iter(|| {
            let cam = &cams[i % cams.len()];
            i += 1;
            let fr = cam.frustum();
            let view = ViewInput {
                eye: cam.eye,
                frustum: &fr,
                scale: 1.0,
                lookahead: None,
            };
            classify(&table, &[&nodes], &view, &mut scratch, &mut out);
            black_box(out.len())
        })
    });
    {
        let mut pager = Pager::new(
            table.clone(),
            PagerOptions {
                capacity: 160,
                ..PagerOptions::default()
            },
        )
        .expect("a pager over the table");
        let mut i = 0usize;
        g.bench_function("plan-berlin-dive-k160", |b| {
            b.iter(|| {
                let cam = &cams[i % cams.len()];
                i += 1;
                let fr = cam.frustum();
                let view = ViewInput {
                    eye: cam.eye,
                    frustum: &fr,
                    scale: 1.0,
                    lookahead: None,
                };
                black_box(pager.plan(&[&nodes], &view).len())
            })
        });
    }
    g.finish();
}

criterion_group!(
    benches,
    sizing,
    packing,
    raster,
    downsampling,
    selection_and_priority
);
criterion_main!(benches);
