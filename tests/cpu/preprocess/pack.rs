//! `preprocess::pack`: cross-check against the `crunch` packer (crates.io) on random rectangle sets, the
//! occupancy both reach, and valid packings of up to 2,000 rectangles at 80–99 % fill (the `pack` bench's
//! sets). Run with `--nocapture` to see the numbers.

use crate::fixtures::pack_sets;
use atlastree::preprocess::pack::{PackOptions, SortOrder, pack, verify_packing};

/// SplitMix64: deterministic, dependency-free.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in `lo..=hi`.
    fn range(&mut self, lo: u32, hi: u32) -> u32 {
        lo + (self.next() % u64::from(hi - lo + 1)) as u32
    }
}

/// A texture area as the area stage makes them: inner + 2·8 border, 4-aligned. Mostly small, some large.
fn random_size(rng: &mut Rng, side: u32) -> [u32; 2] {
    let max_inner = if rng.range(0, 9) == 0 {
        side / 2
    } else {
        side / 16
    };
    let a = |rng: &mut Rng| (rng.range(1, max_inner) + 16).next_multiple_of(4);
    [a(rng), a(rng)]
}

/// Random sizes until their summed area reaches `fill` of the atlas.
fn random_set(rng: &mut Rng, side: u32, fill: f64) -> Vec<[u32; 2]> {
    let cap = f64::from(side) * f64::from(side);
    let mut v = Vec::new();
    let mut area = 0.0;
    while area < fill * cap {
        let s = random_size(rng, side);
        area += f64::from(s[0]) * f64::from(s[1]);
        v.push(s);
    }
    v
}

fn crunch_fits(sizes: &[[u32; 2]], side: u32) -> bool {
    let items = sizes
        .iter()
        .enumerate()
        .map(|(i, s)| crunch::Item::new(i, s[0] as usize, s[1] as usize, crunch::Rotation::None));
    match crunch::pack(crunch::Rect::of_size(side as usize, side as usize), items) {
        Ok(packed) => {
            // Sanity of the reference itself.
            let mut pos = vec![[0u32; 2]; sizes.len()];
            for p in &packed {
                pos[p.data] = [p.rect.x as u32, p.rect.y as u32];
                assert_eq!(
                    [p.rect.w as u32, p.rect.h as u32],
                    sizes[p.data],
                    "crunch rotated"
                );
            }
            assert_eq!(packed.len(), sizes.len());
            verify_packing(sizes, &pos, side).expect("crunch result invalid");
            true
        }
        Err(_) => false,
    }
}

fn ours_fits(sizes: &[[u32; 2]], side: u32) -> bool {
    match pack(
        sizes,
        &PackOptions {
            atlas_size: side,
            ..Default::default()
        },
    ) {
        Ok(p) => {
            verify_packing(sizes, &p.positions, side).expect("our result invalid");
            true
        }
        Err(_) => false,
    }
}

#[test]
fn fits_whenever_crunch_fits() {
    let side = 1024;
    let mut rng = Rng(0x5EED);
    let (mut trials, mut ref_fit, mut our_fit, mut both) = (0u32, 0u32, 0u32, 0u32);
    for trial in 0..300 {
        let fill = 0.55 + 0.40 * f64::from(trial % 20) / 19.0;
        let sizes = random_set(&mut rng, side, fill);
        let (r, o) = (crunch_fits(&sizes, side), ours_fits(&sizes, side));
        trials += 1;
        ref_fit += u32::from(r);
        our_fit += u32::from(o);
        both += u32::from(r && o);
    }
    let rate = f64::from(both) / f64::from(ref_fit.max(1));
    println!(
        "{trials} sets (fill 55–95 %): crunch fits {ref_fit}, ours fits {our_fit}, \
         ours fits when crunch fits: {both}/{ref_fit} = {rate:.3}"
    );
    assert!(
        ref_fit > 20,
        "the test must include sets the reference can pack ({ref_fit})"
    );
    assert!(our_fit >= ref_fit, "ours {our_fit} < crunch {ref_fit}");
    assert!(
        rate >= 0.98,
        "ours failed on {} sets crunch packed",
        ref_fit - both
    );
}

/// Largest prefix of a random sequence that packs: the occupancy each packer reaches.
fn max_prefix_occupancy(
    sizes: &[[u32; 2]],
    side: u32,
    fits: impl Fn(&[[u32; 2]], u32) -> bool,
) -> f64 {
    let mut k = 0;
    while k < sizes.len() && fits(&sizes[..=k], side) {
        k += 1;
    }
    let area: u64 = sizes[..k]
        .iter()
        .map(|s| u64::from(s[0]) * u64::from(s[1]))
        .sum();
    area as f64 / (f64::from(side) * f64::from(side))
}

#[test]
fn occupancy_reached_is_at_least_crunchs() {
    let side = 512;
    let mut rng = Rng(42);
    let (mut ours, mut theirs) = (Vec::new(), Vec::new());
    for _ in 0..30 {
        let sizes = random_set(&mut rng, side, 1.05);
        ours.push(max_prefix_occupancy(&sizes, side, ours_fits));
        theirs.push(max_prefix_occupancy(&sizes, side, crunch_fits));
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
    let wins = ours.iter().zip(&theirs).filter(|(o, t)| o >= t).count();
    println!(
        "max prefix occupancy over 30 sequences: ours mean {:.3} min {:.3}; crunch mean {:.3} min {:.3}; \
         ours ≥ crunch in {wins}/30",
        mean(&ours),
        min(&ours),
        mean(&theirs),
        min(&theirs)
    );
    assert!(
        mean(&ours) >= mean(&theirs),
        "ours {:?} crunch {:?}",
        ours,
        theirs
    );
    assert!(mean(&ours) > 0.80, "mean occupancy {:.3}", mean(&ours));
}

/// The `pack` bench's sets (50–2,000 rectangles, fill 0.80–0.99), with every sort order and with the
/// global best fit alone: every packing returned is valid, and every set up to 90 % fill packs.
#[test]
fn bench_sets_pack_validly_up_to_90_percent_fill() {
    for (name, side, fill, sizes) in pack_sets::cases() {
        let all = PackOptions {
            atlas_size: side,
            ..Default::default()
        };
        let global_only = PackOptions {
            atlas_size: side,
            orders: vec![SortOrder::GlobalBestFit],
        };
        for opts in [all, global_only] {
            let result = pack(&sizes, &opts);
            println!(
                "{name} (occupancy {:.3}) {:?}: {:?}",
                pack_sets::occupancy(&sizes, side),
                opts.orders,
                result.as_ref().map(|p| p.order_used)
            );
            match result {
                Ok(p) => verify_packing(&sizes, &p.positions, side)
                    .unwrap_or_else(|e| panic!("{name}: invalid packing: {e}")),
                Err(e) if fill <= 0.90 && opts.orders.len() > 1 => {
                    panic!("{name}: no packing at fill {fill}: {e:?}")
                }
                Err(_) => {}
            }
        }
    }
}
