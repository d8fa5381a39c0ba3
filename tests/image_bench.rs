//! Throughput of the image operations (ignored by default; run with
//! `cargo test --test image_bench -- --ignored --nocapture`). Asserts only that the work was done.

use atlastree::preprocess::image_ops::{
    LinearImage, MipChain, RectJob, draw_rect, halve, mip_chain_rgba8,
};
use atlastree::scene::Wrap;
use std::time::Instant;

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

/// Best of `runs` wall times in seconds.
fn best_of(runs: usize, mut f: impl FnMut()) -> f64 {
    (0..runs)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
#[ignore]
fn throughput() {
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
    let texels = 1024.0 * 1024.0;
    for (label, uv_max) in [
        ("magnify 512→1024 (1 tap)", 1.0),
        ("minify 4× (2×2 taps)", 8.0),
        ("minify 1.5× (2×2 taps)", 3.0),
    ] {
        let t = best_of(3, || draw_rect(&mut dst, &job(uv_max), &src).unwrap());
        eprintln!(
            "draw_rect 1024² {label}: {:.1} ms, {:.1} Mtexel/s",
            t * 1e3,
            texels / t / 1e6
        );
    }
    let big = gradient(1024);
    let t = best_of(3, || assert_eq!(halve(&big).width, 512));
    eprintln!(
        "halve 1024² → 512²: {:.1} ms, {:.1} Msource-texel/s",
        t * 1e3,
        texels / t / 1e6
    );
    let t = best_of(3, || assert!(!mip_chain_rgba8(&big).is_empty()));
    eprintln!(
        "mip_chain_rgba8 1024² (11 levels, encode incl.): {:.1} ms",
        t * 1e3
    );
    let t = best_of(3, || assert_eq!(big.to_rgba8().len(), 4 << 20));
    eprintln!(
        "to_rgba8 1024²: {:.1} ms, {:.1} Mtexel/s",
        t * 1e3,
        texels / t / 1e6
    );
}
