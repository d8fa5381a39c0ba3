//! The shader's rect arithmetic in f32 (`RectMap::texel_f32`) against the f64 reference, and its
//! footprint rules at a rect's edges.

/// `RectMap::texel_f32` (the shader's arithmetic in f32) agrees with the f64 reference
/// `model::transform::rect_texel` on the grid of `tests/fixtures/shader_math.rs` (every wrap mode, rect
/// edges, UVs up to 65536 periods out, levels to 24), within the tolerance stated there, and the f32 level
/// transform of its texel with the f64 one within 2⁻²⁴; near-branch samples are few.
#[test]
fn texel_f32_agrees_with_f64_reference() {
    use crate::fixtures::shader_math::{ATLAS, F64Check, check_f64, maps, rects, samples};
    use atlastree::ids::Level;
    use atlastree::model::transform::{atlas_uv_at, atlas_uv_at_f32};
    let rects = rects();
    let maps = maps(&rects);
    let samples = samples(&rects);
    let (mut agree, mut near, mut near_step) = (0usize, 0usize, 0usize);
    let mut failures = Vec::new();
    for s in &samples {
        let (texel, gx, gy) = maps[s.rect].texel_f32(s.uv, s.ddx, s.ddy, s.level_texels());
        // Gradients stay finite, zero footprints (constant UVs) included: they go to textureSampleGrad.
        if !(gx.is_finite() && gy.is_finite()) {
            failures.push(format!("{s:?}: gradients {gx} {gy} not finite"));
        }
        // Then the level transform, in f32 as the shader and in f64: one rounding of a value in [0, 1].
        let (k, j) = (Level(s.leaf_level), Level(s.level));
        let leaf_uv = texel / ATLAS as f32;
        let f32_uv = atlas_uv_at_f32(leaf_uv, s.cell, k, j).as_dvec2();
        let f64_uv = atlas_uv_at(leaf_uv.as_dvec2(), s.cell, k, j);
        if (f32_uv - f64_uv).abs().max_element() > 2f64.powi(-24) {
            failures.push(format!("{s:?}: atlas uv {f32_uv} in f32, {f64_uv} in f64"));
        }
        match check_f64(&rects[s.rect], s, texel) {
            Ok(F64Check::Agrees) => agree += 1,
            // The texel agreed; the GPU test allows its gradients the step's factor.
            Ok(F64Check::AgreesTexelNearStep) => {
                agree += 1;
                near_step += 1;
            }
            Ok(F64Check::NearBranch) => near += 1,
            Err(e) => failures.push(e),
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} samples disagree:\n{}",
        failures.len(),
        samples.len(),
        failures[..failures.len().min(20)].join("\n")
    );
    assert_eq!(agree + near, samples.len());
    // At most 2% sit on a branch boundary (280 of 22,400: constant UVs at K = 10, j = 4, where a 64-texel
    // outer rectangle leaves lo == hi).
    assert!(
        near * 50 <= samples.len(),
        "{near} near-branch samples of {}",
        samples.len()
    );
    println!("{agree} agree, {near} near a branch, {near_step} near a step of the footprint cap");
}

/// A palette cell's point rect (1 × 1 inner, 8-texel border) shows its mean at every level and footprint;
/// a constant UV (zero gradients) on a wider rect is sampled while the drawn level's bilinear taps stay
/// inside the outer rect, its mean beyond (`POINT_REACH` drawn texels from the nearer outer edge).
#[test]
fn a_constant_uv_shows_the_mean_where_its_taps_would_leave_the_rect() {
    use atlastree::model::{AtlasRect, RectWrap};
    use atlastree::render::wgsl::tree::{POINT_REACH, RectMap};
    use atlastree::scene::AlphaMode;
    use glam::Vec2;
    let rect = AtlasRect {
        material: atlastree::ids::MaterialId(0),
        outer: [40, 60, 20, 20],
        inner: [48, 68, 1, 1],
        uv_min: [0.53125; 2],
        uv_max: [0.53125; 2],
        wrap: [RectWrap::Linear; 2],
        capped: [false; 2],
        mean: [10, 20, 30, 255],
    };
    let map = RectMap::new(&rect, AlphaMode::Opaque);
    let uv = Vec2::splat(0.53125);
    // A zero UV span counts as one UV: the UV maps onto the inner texel's corner, 8 texels from the
    // outer edges (the border is the cell's colour, so the bilinear taps read it alone).
    // One inner texel: its mean at every level, with gradients zero or an ulp off zero (a constant UV
    // interpolated across a triangle; they took the sampled branch and read neighbouring rects).
    for level_texels in [1.0f32, 4.0, 8.0, 16.0] {
        for jitter in [0.0f32, 1e-7, 3e-6] {
            let d = Vec2::new(jitter, -jitter * 0.5);
            let s = map.sample_f32(uv, d, d.perp(), level_texels);
            assert!(
                s.flat,
                "level texels {level_texels}, jitter {jitter}: {s:?}"
            );
            assert_eq!(s.mix_mean, 1.0);
            if jitter == 0.0 {
                assert_eq!((s.gx, s.gy), (Vec2::ZERO, Vec2::ZERO), "{s:?}");
            }
        }
    }
    // One inner texel holding a UV span (a 4 × 4 checker's quarter texel magnified, or a 2 × 2 texture in
    // a leaf scaled to half) is no point: sampled like any rect near the inner texel (all of them drew
    // flat for a while, 5 dB against the original on the reviewer's checker).
    let span = RectMap::new(
        &AtlasRect {
            uv_max: [0.6; 2],
            ..rect.clone()
        },
        AlphaMode::Opaque,
    );
    assert_eq!((map.point, span.point), (1, 0));
    let s = span.sample_f32(
        Vec2::splat(0.55),
        Vec2::new(1e-3, 0.0),
        Vec2::new(0.0, 1e-3),
        1.0,
    );
    assert!(!s.flat, "{s:?}");
    // A wider rect (2 × 1 inner) keeps the rule by reach: sampled while the taps stay inside, its mean
    // beyond (`POINT_REACH` drawn texels from the nearer outer edge).
    let wide = RectMap::new(
        &AtlasRect {
            outer: [40, 60, 21, 20],
            inner: [48, 68, 2, 1],
            ..rect
        },
        AlphaMode::Opaque,
    );
    for (level_texels, flat) in [(1.0f32, false), (4.0, false), (8.0, true), (16.0, true)] {
        let s = wide.sample_f32(uv, Vec2::ZERO, Vec2::ZERO, level_texels);
        assert_eq!(s.flat, flat, "level texels {level_texels}: {s:?}");
        assert_eq!(flat, 8.0 < POINT_REACH * level_texels);
        assert_eq!((s.gx, s.gy), (Vec2::ZERO, Vec2::ZERO), "{s:?}");
        assert_eq!(s.mix_mean, if flat { 1.0 } else { 0.0 });
        if !flat {
            assert_eq!(s.texel, Vec2::new(48.0, 68.0));
        }
    }
}

/// A footprint that covers an elongated rect's short side alone (992 × 16 texels, ~20 texels a pixel
/// along the strip) averages that side only: the strip keeps its detail along its length. (It was
/// flattened whole, so a 1024 × 16 gradient texture seen from a few metres drew as one colour.) A
/// footprint over both sides is flat (it shows the rect's mean; its texel is the inner centre).
#[test]
fn a_footprint_over_a_strips_short_side_keeps_its_length() {
    use crate::fixtures::shader_math::rects;
    use atlastree::render::wgsl::tree::RectMap;
    use atlastree::scene::AlphaMode;
    use glam::Vec2;
    let rects = rects();
    let strip = rects
        .iter()
        .find(|r| r.inner[2] == 992 && r.inner[3] == 16)
        .unwrap();
    let map = RectMap::new(strip, AlphaMode::Opaque);
    let centre = Vec2::new(16.0 + 496.0, 596.0 + 8.0);
    let (ddx, ddy) = (Vec2::new(0.02, 0.0), Vec2::new(0.0, 0.005));
    for u in [0.25f32, 0.75] {
        let (texel, gx, gy) = map.texel_f32(Vec2::new(u, 0.3), ddx, ddy, 1.0);
        assert!(
            (texel.x - (16.0 + u * 992.0)).abs() < 1e-3,
            "u {u}: {texel}"
        );
        assert_eq!(texel.y, centre.y, "u {u}: {texel}");
        // Sharpened only as far as the isotropic filter needs to stay inside the outer rectangle across
        // the strip (24 texels from the centre): the longer gradient, along the strip, sets its mip on
        // both axes (lod 3.99: the coarser mip's 16-texel texels reach 24 texels), far from the period
        // branch.
        let k = gx.x / (ddx.x * 992.0);
        assert!(
            (gx - ddx * 992.0 * k).abs().max_element() < 1e-5,
            "u {u}: {gx}"
        );
        assert!(
            (gy - ddy * 16.0 * k).abs().max_element() < 1e-6,
            "u {u}: {gy}"
        );
        assert_eq!(
            k,
            RectMap::footprint_cap(24.0, 1.0) / (ddx.x * 992.0),
            "u {u}"
        );
        assert!(k > 0.75 && k < 1.0, "u {u}: k {k}");
    }
    let (texel, ..) = map.texel_f32(Vec2::new(0.25, 0.3), ddx * 100.0, ddy * 100.0, 1.0);
    assert_eq!(texel, centre);
}
