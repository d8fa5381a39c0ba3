//! `cargo bench --bench store`: the paging file (`store`) at 10k nodes / 1M vertices (two full depth-6
//! trees of `tests/fixtures/store_forest.rs`, 128 vertices and triangles per leaf, 64-byte blocks): table
//! sizes per node, leaf, vertex and triangle (printed once), then the time of a parallel write, of
//! open + validate with mmap and with read, and of `verify_blocks`. Round trips, corruption and atomic
//! publication are `tests/cpu/store.rs`.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "benchmark code: a failed unwrap fails the run loudly"
)]

#[path = "../../tests/fixtures/store_forest.rs"]
mod store_forest;

use atlastree::model::TreeKind;
use atlastree::store::format::Section;
use atlastree::store::{LoadMode, TreeFile};
use atlastree::texfmt::TexFormat;
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use store_forest::{TreeSpec, synth_forest, write_forest};

fn bench(c: &mut Criterion) {
    let spec = TreeSpec {
        kind: TreeKind::Opaque,
        depth: 6,
        full: true,
        verts_per_leaf: 128,
        tris_per_leaf: 128,
        block_bytes: (64, 64),
        max_original_blocks: 0,
        format: TexFormat::Bc3,
    };
    let alpha = TreeSpec {
        kind: TreeKind::Alpha,
        ..spec
    };
    let forest = synth_forest(31, &[spec, alpha]);
    let nodes: usize = forest.trees.iter().map(|t| t.nodes.len()).sum();
    let leaves: usize = forest.trees.iter().map(|t| t.leaves.len()).sum();
    let verts: usize = forest.trees.iter().map(|t| t.vertices.len()).sum();
    let tris: usize = forest.trees.iter().map(|t| t.source_triangles.len()).sum();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.atlastree");
    let s = write_forest(&path, &forest, 31);
    eprintln!(
        "nodes {nodes} leaves {leaves} vertices {verts} triangles {tris} blocks {}",
        s.blocks
    );
    for sec in Section::ALL {
        eprintln!("  {:>16}: {:>10} bytes", sec.name(), s.bytes(sec));
    }
    eprintln!(
        "  per node {} B, per leaf {} B (+ rects/originals), per vertex {} B, per triangle {} B; tables end {} B",
        s.bytes(Section::Nodes) / nodes as u64,
        s.bytes(Section::Leaves) / leaves as u64,
        s.bytes(Section::Vertices) / verts as u64,
        (s.bytes(Section::Indices) + s.bytes(Section::SourceTriangles)) / tris as u64,
        s.tables_end
    );
    eprintln!("  file {} B, padding {} B", s.total, s.padding_bytes);

    let mut g = c.benchmark_group("store-10k-nodes-1m-vertices");
    g.sample_size(10);
    let scratch = dir.path().join("again.atlastree");
    g.bench_function("write", |b| {
        b.iter(|| black_box(write_forest(&scratch, &forest, 31).total))
    });
    for (name, mode) in [
        ("open-validate-mmap", LoadMode::Mmap),
        ("open-validate-read", LoadMode::Read),
    ] {
        g.bench_function(name, |b| {
            b.iter(|| {
                let f = TreeFile::open_with(&path, mode).unwrap();
                black_box(f.tree(0).unwrap().nodes.len())
            })
        });
    }
    let f = TreeFile::open(&path).unwrap();
    g.bench_function("verify_blocks", |b| b.iter(|| f.verify_blocks().unwrap()));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
