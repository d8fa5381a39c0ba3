//! `cargo bench --bench pack`: packing time (`preprocess::pack`, MaxRects) for 50, 500 and 2,000
//! rectangles, mostly tiny or uniformly random, grown to 80, 90, 95 and 99 % of a 1024² or 2048² atlas
//! (`tests/fixtures/pack_sets.rs`): every sort order in turn until one places everything (`all-orders`,
//! the build's default), and the global best fit alone. Sets that do not pack time the whole failed
//! search. Which sets pack, and that the packings are valid, is
//! `tests/cpu/preprocess/pack.rs::bench_sets_pack_validly_up_to_90_percent_fill`.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "benchmark code: a failed unwrap fails the run loudly"
)]

#[path = "../../tests/fixtures/pack_sets.rs"]
mod pack_sets;

use atlastree::preprocess::pack::{PackOptions, SortOrder, pack};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("pack");
    // 64 cases of a few ms each at most: short windows keep the whole run near two minutes.
    g.warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1));
    for (name, side, _, sizes) in pack_sets::cases() {
        g.throughput(Throughput::Elements(sizes.len() as u64));
        let all = PackOptions {
            atlas_size: side,
            ..Default::default()
        };
        let global = PackOptions {
            atlas_size: side,
            orders: vec![SortOrder::GlobalBestFit],
        };
        for (label, opts) in [("all-orders", all), ("global-alone", global)] {
            let outcome = pack(&sizes, &opts).map(|p| p.order_used);
            eprintln!(
                "pack/{name}/{label}: occupancy {:.3} -> {outcome:?}",
                pack_sets::occupancy(&sizes, side)
            );
            g.bench_function(format!("{name}/{label}"), |b| {
                b.iter(|| black_box(pack(black_box(&sizes), &opts).is_ok()))
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
