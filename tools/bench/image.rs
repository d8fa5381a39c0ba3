//! `cargo bench --bench image`: throughput of the image operations of the build
//! (`preprocess::image_ops`) on 1024² images: `draw_rect` magnifying and minifying a 512² source (wrapped),
//! one `halve`, a whole RGBA8 mip chain (`mip_chain_rgba8`, 11 levels, encode included), `to_rgba8`
//! (linear → sRGB8), `from_decoded` (sRGB8 → linear, the first step after decoding every image) and
//! `encode_chain` (a 1024² RGBA8 chain to BC1 and BC7, each level's error measured as the build does).
//! Criterion prints texels/s next to the time (per destination texel, or per source texel for `halve`).
//! Their correctness is `tests/cpu/preprocess/image_ops.rs`.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "benchmark code: a failed unwrap fails the run loudly"
)]

use atlastree::preprocess::image_ops::{
    LinearImage, MipChain, RectJob, draw_rect, halve, mip_chain_rgba8,
};
use atlastree::scene::{DecodedImage, Wrap};
use atlastree::texfmt::{TexFormat, encode_chain};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;

fn gradient(n: u32) -> LinearImage {
    let data = (0..n * n).map(|i| {
        let (x, y) = ((i % n) as f32 / n as f32, (i / n) as f32 / n as f32);
        [x, y, 0.5 * (x + y), 1.0]
    });
    LinearImage {
        width: n,
        height: n,
        data: data.collect(),
    }
}

const TEXELS: u64 = 1024 * 1024;

/// `img` premultiplied by a blob pattern of alpha 1 and 0 (a cutout texture's leaves and gaps).
fn with_leaves(img: &LinearImage) -> LinearImage {
    let w = img.width as usize;
    let data = img.data.iter().enumerate().map(|(i, &[r, g, b, _])| {
        let (x, y) = ((i % w) as f32, (i / w) as f32);
        let leaf = (x * 0.05).sin() * (y * 0.07).cos() + (x * 0.013 + y * 0.021).sin() > 0.6;
        if leaf { [r, g, b, 1.0] } else { [0.0; 4] }
    });
    LinearImage {
        width: img.width,
        height: img.height,
        data: data.collect(),
    }
}

fn draw(c: &mut Criterion) {
    let src = MipChain::build(gradient(512));
    let mut dst = LinearImage::new_filled(1024, 1024, [0.0; 4]);
    let job = |uv_max: f64| RectJob {
        outer: [0, 0, 1024, 1024],
        inner: [8, 8, 1008, 1008],
        uv_min: [0.0; 2],
        uv_max: [uv_max; 2],
        wrap: [Wrap::Repeat; 2],
        factor: [1.0; 4],
    };
    let mut g = c.benchmark_group("draw_rect-1024");
    g.throughput(Throughput::Elements(TEXELS));
    for (name, uv_max) in [
        // 512 → 1024: one tap per texel.
        ("magnify-2x", 1.0),
        // 2×2 taps per texel.
        ("minify-4x", 8.0),
        ("minify-1.5x", 3.0),
    ] {
        let job = job(uv_max);
        g.bench_function(name, |b| {
            b.iter(|| draw_rect(black_box(&mut dst), &job, &src).unwrap())
        });
    }
    g.finish();
}

fn levels(c: &mut Criterion) {
    let big = gradient(1024);
    let mut g = c.benchmark_group("image-1024");
    g.throughput(Throughput::Elements(TEXELS));
    g.bench_function("halve", |b| b.iter(|| black_box(halve(&big).width)));
    g.bench_function("mip_chain_rgba8", |b| {
        b.iter(|| black_box(mip_chain_rgba8(&big).len()))
    });
    g.bench_function("to_rgba8", |b| b.iter(|| black_box(big.to_rgba8().len())));
    // Foliage: leaves of a cutout texture in blobs, ~60 % of the texels transparent, so the colour
    // bleed into them runs over most of the level.
    let foliage = with_leaves(&big);
    g.bench_function("to_rgba8-foliage", |b| {
        b.iter(|| black_box(foliage.to_rgba8().len()))
    });
    // 128² (256 KiB of f32 texels, cache-resident, one task): the conversion itself, without memory traffic.
    let small = gradient(128);
    g.bench_function("to_rgba8-128x64", |b| {
        b.iter(|| {
            (0..64)
                .map(|_| black_box(small.to_rgba8().len()))
                .sum::<usize>()
        })
    });
    let decoded = DecodedImage {
        width: 1024,
        height: 1024,
        pixels: big
            .to_rgba8()
            .chunks_exact(4)
            .map(|p| [p[0], p[1], p[2], p[3]])
            .collect(),
    };
    g.bench_function("from_decoded", |b| {
        b.iter(|| black_box(LinearImage::from_decoded(&decoded).unwrap().width))
    });
    g.finish();
}

/// A photo-like 1024² RGBA8 chain: a gradient with per-texel noise, so blocks are neither flat nor random.
fn noisy_chain() -> Vec<u8> {
    let mut img = gradient(1024);
    let mut rng = atlastree::util::XorShift64::new(0x9e37_79b9_7f4a_7c15);
    for p in &mut img.data {
        let n = (rng.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        p[0] = (p[0] + 0.1 * n).min(1.0);
        p[1] = (p[1] * (0.9 + 0.1 * n)).min(1.0);
    }
    mip_chain_rgba8(&img)
}

fn encode(c: &mut Criterion) {
    let chain = noisy_chain();
    let mut g = c.benchmark_group("encode_chain-1024");
    g.throughput(Throughput::Elements(TEXELS * 4 / 3));
    for (name, format) in [("bc1", TexFormat::Bc1), ("bc7", TexFormat::Bc7)] {
        g.bench_function(name, |b| {
            b.iter(|| black_box(encode_chain(format, &chain, 1024, 3).unwrap().sse))
        });
    }
    g.finish();
}

criterion_group!(benches, draw, levels, encode);
criterion_main!(benches);
