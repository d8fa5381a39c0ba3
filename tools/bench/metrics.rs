//! `cargo bench --bench metrics`: image metrics of `report::metrics` on one 800 × 600 RGBA8 frame pair
//! (a structured picture against a shifted, noisier copy). One iteration = one frame pair.
//! Target: SSIM well under the ~10–20 ms a lavapipe frame takes, so per-frame accuracy is affordable in
//! `sweep`.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "benchmark code: a failed unwrap fails the run loudly"
)]

use atlastree::report::metrics::{psnr, ssim};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;

const W: u32 = 800;
const H: u32 = 600;

fn frames() -> (Vec<u8>, Vec<u8>) {
    let mut a = Vec::with_capacity((W * H * 4) as usize);
    let mut b = Vec::with_capacity((W * H * 4) as usize);
    let mut s = 0x9e37_79b9_u32;
    for y in 0..H {
        for x in 0..W {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            let v = (128.0 + 90.0 * ((x as f32) * 0.05).sin() * ((y as f32) * 0.03).cos()) as u8;
            let n = (s % 17) as u8;
            a.extend_from_slice(&[v, v / 2, 255 - v, 255]);
            b.extend_from_slice(&[v.saturating_add(n), v / 2, (255 - v).saturating_sub(n), 255]);
        }
    }
    (a, b)
}

fn bench(c: &mut Criterion) {
    let (a, b) = frames();
    let mut g = c.benchmark_group("metrics_800x600");
    g.throughput(Throughput::Elements(u64::from(W * H)));
    g.bench_function("psnr", |bch| {
        bch.iter(|| black_box(psnr(black_box(&a), black_box(&b), W, H).unwrap()))
    });
    g.bench_function("ssim", |bch| {
        bch.iter(|| black_box(ssim(black_box(&a), black_box(&b), W, H).unwrap()))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
